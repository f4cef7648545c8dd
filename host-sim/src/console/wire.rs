//! What the page and the console say to each other over the WebSocket, as JSON.
//!
//! The console sends `scene` once per connection (the household, the lattice, the names), `trace`
//! once (where the car has been), then a `state` after every change (a tick, a teaching, a pause);
//! `error` answers a message it could not read. The page sends [`Command`]s.

use firmware_core::lattice::{SAMPLES, trajectory};
use firmware_core::{ActionIndex, Feature};
use serde::Deserialize;
use serde_json::{Value, json};

use crate::teach::person::{Spoken, Teaching};
use crate::teach::session::{LinkState, Session};
use crate::world::scenario::{Scenario, Shape};

/// The speeds the console runs at, times the car's 10 Hz.
pub const SPEEDS: [f32; 6] = [0.25, 0.5, 1.0, 2.0, 4.0, 8.0];

/// What the page asks.
#[derive(Clone, Copy, Debug, PartialEq, Deserialize)]
#[serde(tag = "cmd", rename_all = "kebab-case")]
pub enum Command {
    /// Run at the chosen speed.
    Play,
    /// Stop advancing.
    Pause,
    /// Pause and advance one tick.
    Step,
    /// Run at `value` times 10 Hz (one of [`SPEEDS`]).
    Speed {
        /// The factor.
        value: f32,
    },
    /// A teaching about `tick`.
    Teach {
        /// The tick the page showed.
        tick: u32,
        /// What the person did.
        teaching: Teaching,
    },
    /// End the session: write its files and stop the console.
    Finish,
}

/// Where the household's picture (`/map.png`) puts the world: `origin` is the world point of the
/// picture's lower-left corner, `metres_per_pixel` its scale.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PictureFrame {
    /// Width in pixels.
    pub width: usize,
    /// Height in pixels.
    pub height: usize,
    /// World `(x, y)` of the lower-left corner (m).
    pub origin: (f64, f64),
    /// Metres per pixel.
    pub metres_per_pixel: f64,
}

/// The `scene` message.
pub fn scene(
    scenario: &Scenario,
    frame: &PictureFrame,
    session: &Session,
    link: Option<&str>,
) -> Value {
    let objects: Vec<Value> = scenario
        .objects
        .iter()
        .map(|o| {
            let shape = match o.shape {
                Shape::Disc { radius } => json!({"disc": {"radius": radius}}),
                Shape::Rect { width, height, yaw } => {
                    json!({"rect": {"width": width, "height": height, "yaw": yaw}})
                }
            };
            json!({"class": o.class.name(), "x": o.centre.x, "y": o.centre.y, "shape": shape})
        })
        .collect();
    // Each trajectory as the rear axle's path in the car frame (x forward, y left), from the
    // axle.
    let lattice: Vec<Value> = ActionIndex::all()
        .map(|a| {
            let t = trajectory(a);
            let mut points = vec![[0.0f32, 0.0]];
            points.extend(t.poses().iter().take(SAMPLES).map(|p| [p.x, p.y]));
            json!(points)
        })
        .collect();
    let statements: Vec<Value> = Spoken::ALL
        .iter()
        .map(|s| json!({"name": s.name(), "paper": Spoken::PAPER.contains(s)}))
        .collect();
    let path_points: Vec<[f64; 2]> = scenario.path.points().iter().map(|p| [p.x, p.y]).collect();
    let config = session.config();
    let teacher = config.teacher();
    json!({
        "type": "scene",
        "scenario": scenario.name,
        "description": scenario.description,
        "picture": {
            "width": frame.width,
            "height": frame.height,
            "origin": [frame.origin.0, frame.origin.1],
            "metres_per_pixel": frame.metres_per_pixel,
        },
        "objects": objects,
        "path": {"points": path_points, "closed": scenario.path.is_closed()},
        "start": [scenario.start.x, scenario.start.y, scenario.start.theta],
        "lattice": lattice,
        "features": Feature::ALL.iter().map(|f| f.name()).collect::<Vec<_>>(),
        "statements": statements,
        "kinds": Teaching::KINDS,
        // How many ticks a good/bad label covers: the ticks the learner remembers.
        "span_ticks": firmware_core::agent::TICK_HISTORY,
        "speeds": SPEEDS,
        "learner": config.learner.kind.name(),
        "teacher": teacher.preset,
        "link": link,
        "max_ticks": config.steps,
    })
}

/// What the console is doing besides the session.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Pace {
    /// Advancing on its own.
    pub running: bool,
    /// Times 10 Hz.
    pub speed: f32,
    /// Stopped by the E-stop (until played again).
    pub estopped: bool,
    /// The session has ended.
    pub finished: bool,
    /// Why it ended.
    pub ended_by: Option<String>,
    /// Where its files are.
    pub dir: String,
}

/// A message for the person: refusals, link trouble, the end.
#[derive(Clone, Debug, PartialEq)]
pub struct Notice {
    /// Counts up, so the page shows each once.
    pub seq: u64,
    /// info, warn or error.
    pub level: &'static str,
    /// The words.
    pub text: String,
}

/// The `state` message.
pub fn state(session: &Session, pace: &Pace, notice: Option<&Notice>) -> Value {
    let v = session.view();
    let d = v.decision;
    let j = &v.judgement;
    let last = session.records().last();
    let link = session.link_state().map(|l: LinkState| {
        json!({
            "address": l.address,
            "connected": l.connected,
            "retransmissions": l.stats.retransmissions,
            "stops": l.stats.stops_ignored,
            "car_restarts": l.stats.car_restarts,
            "restores": l.stats.restores,
            "link_errors": l.stats.link_errors,
            "refused": l.stats.refused.mac
                + l.stats.refused.replayed
                + l.stats.refused.stale
                + l.stats.refused.unsynced,
        })
    });
    let snapshot = session.snapshot();
    json!({
        "type": "state",
        "tick": v.tick,
        "running": pace.running,
        "speed": pace.speed,
        "estopped": pace.estopped,
        "finished": pace.finished,
        "ended_by": pace.ended_by,
        "dir": pace.dir,
        "pose": [v.pose.x, v.pose.y, v.pose.theta],
        "allowed": d.allowed.iter().map(|a| a.get()).collect::<Vec<_>>(),
        "chosen": d.action.map(|a| a.get()),
        "choice_now": session.choice_now().map(|a| a.get()),
        "teacher_choice": j.choice.map(|a| a.get()),
        "latent_loss": d.action.map(|a| j.latent_loss(a)),
        "corrections": session.corrections(),
        "teachings": session.counts(),
        "weights": snapshot.state.average,
        "learner_steps": snapshot.state.steps,
        "laps": last.map_or(0, |r| r.lap),
        "progress": last.map_or(0.0, |r| r.progress),
        "reset": last.and_then(|r| r.reset).map(|r| r.name()),
        "link": link,
        "notice": notice.map(|n| json!({"seq": n.seq, "level": n.level, "text": n.text})),
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use firmware_core::Polarity;

    #[test]
    fn commands_are_read_and_bad_ones_refused() {
        let ok = [
            (r#"{"cmd":"play"}"#, Command::Play),
            (r#"{"cmd":"pause"}"#, Command::Pause),
            (r#"{"cmd":"step"}"#, Command::Step),
            (
                r#"{"cmd":"speed","value":0.25}"#,
                Command::Speed { value: 0.25 },
            ),
            (r#"{"cmd":"finish"}"#, Command::Finish),
            (
                r#"{"cmd":"teach","tick":7,"teaching":{"kind":"action","content":{"action":63}}}"#,
                Command::Teach {
                    tick: 7,
                    teaching: Teaching::Action {
                        action: ActionIndex::new(63).unwrap(),
                    },
                },
            ),
            (
                r#"{"cmd":"teach","tick":0,"teaching":{"kind":"estop","content":{}}}"#,
                Command::Teach {
                    tick: 0,
                    teaching: Teaching::Estop {},
                },
            ),
        ];
        for (text, want) in ok {
            assert_eq!(
                serde_json::from_str::<Command>(text).unwrap(),
                want,
                "{text}"
            );
        }
        let said: Command = serde_json::from_str(
            r#"{"cmd":"teach","tick":1,"teaching":{"kind":"statement","content":{"statement":"avoid-stairs"}}}"#,
        )
        .unwrap();
        let Command::Teach {
            teaching: Teaching::Statement { statement },
            ..
        } = said
        else {
            panic!("{said:?}")
        };
        assert_eq!(statement.statement().polarity, Polarity::Avoid);
        for bad in [
            r#"{"cmd":"jump"}"#,
            r#"{"cmd":"speed"}"#,
            r#"{"cmd":"speed","value":"fast"}"#,
            r#"{"cmd":"teach","tick":-1,"teaching":{"kind":"estop","content":{}}}"#,
            r#"{"cmd":"teach","tick":1,"teaching":{"kind":"action","content":{"action":64}}}"#,
            r#"not json"#,
        ] {
            assert!(serde_json::from_str::<Command>(bad).is_err(), "{bad}");
        }
    }
}
