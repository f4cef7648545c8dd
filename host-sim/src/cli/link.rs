//! The learner on the car's controller over a CAN link: the options `run` and `teach` share,
//! and the [`RemoteCar`] they open.

use std::path::Path;

use anyhow::{Context, Result};
use hil_mock::transport::Link;
use host_sim::teach::remote::{RemoteCar, RemoteConfig};

#[derive(clap::Args, Debug)]
pub(crate) struct LinkArgs {
    /// Run the learner on the car's controller over this CAN link (udp://127.0.0.1:PORT,
    /// slcan+tcp://127.0.0.1:PORT, slcan+serial:///dev/…, socketcan://IFACE; `hil_mock serve`
    /// or the firmware at the other end). Without it, the learner runs in this process.
    #[arg(long)]
    pub(crate) link: Option<String>,
    /// With --link: disturb the frames the host sends (drop=P,corrupt=P,duplicate=P,
    /// reorder=P,delay=P,max-delay-ms=N,seed=N).
    #[arg(long, requires = "link")]
    pub(crate) faults: Option<String>,
    /// With --link: the frames the host sends.
    #[arg(long, requires = "link", default_value = "fd")]
    pub(crate) frame_mode: super::Frames,
    /// With --link: wait this long for each answer before sending the request again (ms). The
    /// default suits loopback and CAN; a slow serial line needs more.
    #[arg(long, requires = "link", default_value_t = 20)]
    pub(crate) try_timeout_ms: u64,
    /// With --link: the car's key file (`hil_mock keygen FILE`); without it (or --insecure)
    /// a run over a link refuses to start.
    #[arg(long, requires = "link", conflicts_with = "insecure")]
    pub(crate) key: Option<std::path::PathBuf>,
    /// With --link: use the public all-zero key (anyone on the bus can drive and teach the car).
    #[arg(long, requires = "link")]
    pub(crate) insecure: bool,
}

/// The car over `args.link`, every frame written to `record` (candump format) if given; `None`
/// without `--link`.
pub(crate) fn remote_car(
    args: &LinkArgs,
    record: Option<&Path>,
) -> Result<Option<RemoteCar<Box<dyn Link>>>> {
    use hil_mock::transport::LinkAddress;
    use hil_mock::transport::fault::{FaultConfig, FaultyLink};
    use hil_mock::transport::record::RecordingLink;
    let Some(link) = &args.link else {
        return Ok(None);
    };
    let key = hil_mock::key::choose(args.key.as_deref(), args.insecure, "host-sim")?;
    let address: LinkAddress = link.parse()?;
    let faults = args
        .faults
        .as_deref()
        .map(|f| f.parse::<FaultConfig>().map_err(anyhow::Error::msg))
        .transpose()
        .context("--faults")?;
    let mut link: Box<dyn Link> = match address {
        // A TCP connection ends with the car's process: open it again when the car is back.
        LinkAddress::SlcanTcp(_) => {
            Box::new(hil_mock::transport::reconnect::ReconnectingLink::open(
                address,
                std::time::Duration::from_secs(30),
            )?)
        }
        _ => address.open(std::time::Duration::from_secs(30))?,
    };
    if let Some(path) = record {
        link = Box::new(RecordingLink::new(link, path, "can0")?);
    }
    if let Some(f) = faults {
        link = Box::new(FaultyLink::new(link, f));
    }
    eprintln!(
        "host-sim: the learner runs on the car, over {}",
        link.describe()
    );
    Ok(Some(RemoteCar::new(
        link,
        RemoteConfig {
            mode: args.frame_mode.0,
            try_timeout: std::time::Duration::from_millis(args.try_timeout_ms.max(1)),
            ..RemoteConfig::new(key)
        },
    )))
}
