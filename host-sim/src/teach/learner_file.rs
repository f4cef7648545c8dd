//! The learner file of `host-sim run --save-learner FILE` and `--load-learner FILE`: the
//! versioned learner snapshot the car persists, kept in a file, so a learner taught in one
//! household can be tested in another, or a run continued.
//!
//! # Format
//!
//! | bytes | what |
//! |---|---|
//! | 0..8 | [`MAGIC`], `LEARNER` and a zero byte: what the file is |
//! | 8.. | a protocol envelope ([`protocol::seal`]: the protocol version byte, the postcard encoding of a [`LearnerSnapshot`], CRC-16 of both): the form the car's flash pages store the same snapshot in |
//!
//! The snapshot is the whole learner (parameters, iterate, average, AdaGrad accumulator, step
//! count) with its format version ([`firmware_core::SNAPSHOT_VERSION`], the snapshot's first
//! field), so a loaded learner continues bit-identically ([`Learner::restore`]).
//!
//! # What is refused, and in which order
//!
//! A file without the magic bytes (not a learner file), shorter than an envelope (truncated), a
//! CRC that does not match (corrupted), another protocol version (written by another build), a
//! snapshot of another format version, a payload that does not decode or has bytes left over
//! (corrupted), and a snapshot [`Learner::restore`] refuses (its parameters or numbers). Each is
//! a [`LearnerFileError`] naming the file and what to do; nothing is loaded from a refused file.
//! A file is written whole or not at all (a temporary file renamed over it).

use std::path::{Path, PathBuf};

use firmware_core::{Learner, LearnerSnapshot, SNAPSHOT_VERSION};
use protocol::envelope::{ENVELOPE_OVERHEAD, Envelope, EnvelopeError, PROTOCOL_VERSION};

/// The first bytes of every learner file.
pub const MAGIC: [u8; 8] = *b"LEARNER\0";

/// Largest learner file (bytes): the magic, the envelope and the largest snapshot, with room.
pub const MAX_FILE_SIZE: usize = 512;

/// Why a learner file could not be written or read. Every message names the file.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum LearnerFileError {
    /// Reading or writing failed.
    #[error("learner file {path}: {error}")]
    Io {
        /// The file.
        path: PathBuf,
        /// What the OS said (in the message, so not a `source`).
        error: std::io::Error,
    },
    /// The file does not start with [`MAGIC`].
    #[error(
        "learner file {0}: not a learner file (it does not start with the bytes \"LEARNER\\0\"; \
         `host-sim run --save-learner FILE` writes one)"
    )]
    NotALearnerFile(PathBuf),
    /// The bytes after the magic do not hold an intact snapshot.
    #[error("learner file {path}: corrupted ({why}); nothing was loaded")]
    Corrupted {
        /// The file.
        path: PathBuf,
        /// What was found wrong.
        why: &'static str,
    },
    /// The envelope was written by a build speaking another protocol version.
    #[error(
        "learner file {path}: written by a build of protocol version {version}; this build reads \
         version {PROTOCOL_VERSION} (save the learner again with this build)"
    )]
    ProtocolVersion {
        /// The file.
        path: PathBuf,
        /// The version byte it holds.
        version: u8,
    },
    /// The snapshot is of another format version.
    #[error(
        "learner file {path}: a learner snapshot of format version {version}; this build reads \
         version {SNAPSHOT_VERSION} (save the learner again with this build)"
    )]
    SnapshotVersion {
        /// The file.
        path: PathBuf,
        /// The snapshot's version.
        version: u16,
    },
    /// The snapshot decodes but is not a learner ([`Learner::restore`] refused it).
    #[error("learner file {path}: refused: {error}")]
    Refused {
        /// The file.
        path: PathBuf,
        /// Why.
        error: firmware_core::SnapshotError,
    },
    /// The snapshot could not be encoded (cannot happen for a snapshot of this build).
    #[error("learner file {0}: the snapshot does not fit in {MAX_FILE_SIZE} bytes")]
    TooLarge(PathBuf),
}

/// The bytes of the learner file holding `snapshot`.
pub fn encode(snapshot: &LearnerSnapshot) -> Result<Vec<u8>, EnvelopeError> {
    let mut buf = [0u8; MAX_FILE_SIZE];
    let (magic, rest) = buf.split_at_mut(MAGIC.len());
    magic.copy_from_slice(&MAGIC);
    let n = protocol::seal(snapshot, rest)?.len();
    Ok(buf[..MAGIC.len() + n].to_vec())
}

/// The learner the bytes of a learner file hold, after every check of the module
/// documentation; `path` names the file in errors.
pub fn decode(bytes: &[u8], path: &Path) -> Result<LearnerSnapshot, LearnerFileError> {
    let corrupted = |why| LearnerFileError::Corrupted {
        path: path.to_path_buf(),
        why,
    };
    let Some(body) = bytes.strip_prefix(&MAGIC) else {
        return Err(LearnerFileError::NotALearnerFile(path.to_path_buf()));
    };
    let payload = match Envelope::new_checked(body) {
        Ok(env) => env.into_payload(),
        Err(EnvelopeError::Version(version)) => {
            return Err(LearnerFileError::ProtocolVersion {
                path: path.to_path_buf(),
                version,
            });
        }
        Err(EnvelopeError::Crc) => return Err(corrupted("its CRC does not match its bytes")),
        Err(_) => return Err(corrupted("shorter than a snapshot")),
    };
    // The snapshot's first field is its format version: read it before the rest, whose layout
    // depends on it.
    let (version, _) =
        postcard::take_from_bytes::<u16>(payload).map_err(|_| corrupted("no snapshot version"))?;
    if version != SNAPSHOT_VERSION {
        return Err(LearnerFileError::SnapshotVersion {
            path: path.to_path_buf(),
            version,
        });
    }
    let (snapshot, rest) = postcard::take_from_bytes::<LearnerSnapshot>(payload)
        .map_err(|_| corrupted("the snapshot does not decode"))?;
    if !rest.is_empty() {
        return Err(corrupted("bytes after the snapshot"));
    }
    Learner::restore(&snapshot).map_err(|error| LearnerFileError::Refused {
        path: path.to_path_buf(),
        error,
    })?;
    Ok(snapshot)
}

/// Writes `snapshot` to the learner file `path`: whole or not at all (a temporary file beside
/// it, renamed over it).
pub fn save(snapshot: &LearnerSnapshot, path: &Path) -> Result<(), LearnerFileError> {
    let io = |error| LearnerFileError::Io {
        path: path.to_path_buf(),
        error,
    };
    let bytes = encode(snapshot).map_err(|_| LearnerFileError::TooLarge(path.to_path_buf()))?;
    let mut tmp = path.as_os_str().to_owned();
    tmp.push(".tmp");
    let tmp = PathBuf::from(tmp);
    std::fs::write(&tmp, &bytes).map_err(io)?;
    std::fs::rename(&tmp, path).map_err(|e| {
        let _ = std::fs::remove_file(&tmp);
        io(e)
    })
}

/// Reads the learner file `path` (see [`decode`]).
pub fn load(path: &Path) -> Result<LearnerSnapshot, LearnerFileError> {
    let io = |error| LearnerFileError::Io {
        path: path.to_path_buf(),
        error,
    };
    let len = std::fs::metadata(path).map_err(io)?.len();
    if len > MAX_FILE_SIZE as u64 {
        // Not read into memory: no learner file is this large.
        return Err(LearnerFileError::NotALearnerFile(path.to_path_buf()));
    }
    decode(&std::fs::read(path).map_err(io)?, path)
}

/// Bytes of a learner file around its snapshot: the magic and the envelope.
pub const OVERHEAD: usize = MAGIC.len() + ENVELOPE_OVERHEAD;

#[cfg(test)]
mod tests {
    use super::*;
    use firmware_core::{LearnerKind, LearnerParams, LearnerState};

    /// An AdaGrad learner some steps in: every field of the state is non-trivial.
    fn trained() -> LearnerSnapshot {
        let s = LearnerSnapshot {
            version: SNAPSHOT_VERSION,
            params: LearnerParams::new(LearnerKind::AdaGrad).with_step(0.3),
            state: LearnerState {
                iterate: [0.5, -0.125, 1.0e-3, 0.0, 2.0, -1.0],
                average: [0.5, -0.125, 1.0e-3, 0.0, 2.0, -1.0],
                accumulator: [1.0, 0.25, 0.0, 3.0, 0.5, 1.0e-6],
                steps: 17,
            },
        };
        Learner::restore(&s).unwrap();
        s
    }

    fn p() -> &'static Path {
        Path::new("l.bin")
    }

    #[test]
    fn a_snapshot_round_trips_bit_for_bit() {
        let s = trained();
        let bytes = encode(&s).unwrap();
        assert!(bytes.starts_with(&MAGIC));
        assert_eq!(bytes[MAGIC.len()], PROTOCOL_VERSION);
        assert_eq!(decode(&bytes, p()).unwrap(), s);
    }

    #[test]
    fn every_bad_file_is_refused_with_its_reason() {
        let good = encode(&trained()).unwrap();
        let msg = |b: &[u8]| decode(b, p()).unwrap_err().to_string();
        assert!(msg(b"hello, world").contains("not a learner file"));
        assert!(msg(&good[..MAGIC.len() + 1]).contains("corrupted (shorter than a snapshot)"));
        // Every single flipped bit after the magic is caught by the CRC (or the version).
        for i in MAGIC.len()..good.len() {
            let mut b = good.clone();
            b[i] ^= 0x10;
            let e = msg(&b);
            assert!(
                e.contains("corrupted") || e.contains("protocol version"),
                "byte {i}: {e}"
            );
        }
        // Another protocol version, with a valid CRC.
        let mut b = good.clone();
        b[MAGIC.len()] = PROTOCOL_VERSION + 1;
        let n = b.len();
        let crc = protocol::envelope::CRC16.checksum(&b[MAGIC.len()..n - 2]);
        b[n - 2..].copy_from_slice(&crc.to_le_bytes());
        assert!(msg(&b).contains(&format!(
            "protocol version {}; this build reads version {PROTOCOL_VERSION}",
            PROTOCOL_VERSION + 1
        )));
        // Another snapshot version, with a valid CRC.
        let mut s = trained();
        s.version = SNAPSHOT_VERSION + 1;
        let e = msg(&encode(&s).unwrap());
        assert!(
            e.contains(&format!(
                "format version {}; this build reads version {SNAPSHOT_VERSION}",
                SNAPSHOT_VERSION + 1
            )),
            "{e}"
        );
        // A snapshot the learner refuses, with a valid CRC.
        let mut s = trained();
        s.state.iterate[0] = f32::NAN;
        assert!(msg(&encode(&s).unwrap()).contains("refused: snapshot state"));
    }

    #[test]
    fn save_and_load_use_a_file_whole() {
        let dir = tempfile::tempdir().unwrap();
        let f = dir.path().join("learner.bin");
        let s = trained();
        save(&s, &f).unwrap();
        assert_eq!(load(&f).unwrap(), s);
        assert!(!dir.path().join("learner.bin.tmp").exists());
        std::fs::write(&f, vec![0u8; MAX_FILE_SIZE + 1]).unwrap();
        assert!(
            load(&f)
                .unwrap_err()
                .to_string()
                .contains("not a learner file")
        );
        let e = load(&dir.path().join("none.bin")).unwrap_err().to_string();
        assert!(e.contains("none.bin: No such file"), "{e}");
    }
}
