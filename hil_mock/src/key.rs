//! The car's key, on the hosts' and the stand-in's side: key files, `hil_mock keygen`, and the
//! rule that both ends refuse to start without a key unless told `--insecure`.
//!
//! A key file holds the 128-bit key as 32 hexadecimal digits and a newline, nothing else; it
//! is created readable by its owner only (mode 0600). The same file is given to the car
//! (`hil_mock serve --key FILE`, or the firmware image at build time, `CAR_KEY_FILE=FILE`) and
//! to every host that may drive it (`host-sim run --link ... --key FILE`).
//!
//! Without a key, a program that talks to the car refuses to start, unless given `--insecure`:
//! then it uses the publicly known all-zero key ([`Key::INSECURE`]), which authenticates
//! nothing, and says so on stderr every time it starts.
//!
//! Randomness (keys, the car's epochs, the hosts' nonces) comes from the operating system
//! ([`rand::rngs::SysRng`]); none of it reaches a result, so runs stay deterministic.

use std::io::Write;
use std::path::{Path, PathBuf};

use protocol::message::NONCE_LEN;
use protocol::secure::{KEY_LEN, Key, KeyError};
use rand::TryRng;

/// Why a key could not be read, made or chosen.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum KeyFileError {
    /// Reading or writing the file failed.
    #[error("key file {path}: {error}")]
    Io {
        /// The file.
        path: PathBuf,
        /// What the OS said (in the message, so not a `source`: a chain of causes prints it
        /// once).
        error: std::io::Error,
    },
    /// The file does not hold a key.
    #[error(
        "key file {path}: {error} (a key file is 32 hexadecimal digits; `hil_mock keygen FILE` makes one)"
    )]
    Malformed {
        /// The file.
        path: PathBuf,
        /// What is wrong.
        error: KeyError,
    },
    /// The file holds the all-zero key, which is public.
    #[error("key file {0}: the all-zero key is public; use --insecure to say you mean it")]
    Insecure(PathBuf),
    /// `keygen` would overwrite an existing file.
    #[error("{0} exists; keygen does not overwrite a key (remove it first)")]
    Exists(PathBuf),
    /// The operating system gave no randomness.
    #[error("no randomness from the operating system: {0}")]
    Random(String),
    /// Neither `--key` nor `--insecure`, or both.
    #[error("{0}")]
    Choice(String),
}

/// `len` random bytes from the operating system.
fn random_bytes<const N: usize>() -> Result<[u8; N], KeyFileError> {
    let mut out = [0u8; N];
    rand::rngs::SysRng
        .try_fill_bytes(&mut out)
        .map_err(|e| KeyFileError::Random(e.to_string()))?;
    Ok(out)
}

/// A new random key.
pub fn random_key() -> Result<Key, KeyFileError> {
    loop {
        let k = Key::new(random_bytes::<KEY_LEN>()?);
        if !k.is_insecure() {
            return Ok(k);
        }
    }
}

/// A random epoch for a car's start (never 0).
pub fn random_epoch() -> Result<u32, KeyFileError> {
    loop {
        let e = u32::from_le_bytes(random_bytes::<4>()?);
        if e != 0 {
            return Ok(e);
        }
    }
}

/// A random nonce for a host's hello.
pub fn random_nonce() -> Result<[u8; NONCE_LEN], KeyFileError> {
    random_bytes()
}

/// Reads the key in `path`. The all-zero key is refused (it is `--insecure`'s).
pub fn read_key_file(path: &Path) -> Result<Key, KeyFileError> {
    let text = std::fs::read(path).map_err(|error| KeyFileError::Io {
        path: path.to_path_buf(),
        error,
    })?;
    let malformed = |error| KeyFileError::Malformed {
        path: path.to_path_buf(),
        error,
    };
    let text = std::str::from_utf8(&text).map_err(|_| malformed(KeyError::NotHex(0)))?;
    let key = Key::from_hex(text).map_err(malformed)?;
    if key.is_insecure() {
        return Err(KeyFileError::Insecure(path.to_path_buf()));
    }
    Ok(key)
}

/// Writes a new random key to `path` (mode 0600), refusing to overwrite a file.
pub fn keygen(path: &Path) -> Result<Key, KeyFileError> {
    let key = random_key()?;
    let io = |error| KeyFileError::Io {
        path: path.to_path_buf(),
        error,
    };
    let mut options = std::fs::OpenOptions::new();
    options.write(true).create_new(true);
    #[cfg(unix)]
    {
        use std::os::unix::fs::OpenOptionsExt;
        options.mode(0o600);
    }
    let mut file = options.open(path).map_err(|e| {
        if e.kind() == std::io::ErrorKind::AlreadyExists {
            KeyFileError::Exists(path.to_path_buf())
        } else {
            io(e)
        }
    })?;
    file.write_all(&key.to_hex()).map_err(io)?;
    file.write_all(b"\n").map_err(io)?;
    file.sync_all().map_err(io)?;
    Ok(key)
}

/// The key a program starts with: the one in `key_file`, or with `insecure` the public all-zero
/// key, announced on stderr by `program` (every start). Neither, or both, is an error.
pub fn choose(key_file: Option<&Path>, insecure: bool, program: &str) -> Result<Key, KeyFileError> {
    match (key_file, insecure) {
        (Some(path), false) => read_key_file(path),
        (None, true) => {
            eprintln!(
                "{program}: WARNING: --insecure: messages are authenticated with the public \
                 all-zero key; anyone who can send a frame can drive and teach this car"
            );
            Ok(Key::INSECURE)
        }
        (None, false) => Err(KeyFileError::Choice(
            "no key: give --key FILE (`hil_mock keygen FILE` makes one; the car and its hosts \
             share it), or --insecure to run with the public all-zero key"
                .into(),
        )),
        (Some(_), true) => Err(KeyFileError::Choice(
            "--key and --insecure exclude each other".into(),
        )),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn keygen_writes_a_private_key_file_that_reads_back() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("car.key");
        let key = keygen(&path).unwrap();
        assert_eq!(read_key_file(&path).unwrap(), key);
        let text = std::fs::read_to_string(&path).unwrap();
        assert_eq!(text.len(), 2 * KEY_LEN + 1);
        #[cfg(unix)]
        {
            use std::os::unix::fs::PermissionsExt;
            let mode = std::fs::metadata(&path).unwrap().permissions().mode();
            assert_eq!(mode & 0o777, 0o600);
        }
        // Never overwritten; two keys differ.
        assert!(matches!(keygen(&path), Err(KeyFileError::Exists(_))));
        let other = dir.path().join("other.key");
        assert_ne!(keygen(&other).unwrap(), key);
    }

    #[test]
    fn bad_key_files_and_choices_are_clear_errors() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("bad.key");
        for (text, what) in [
            (&b"0011"[..], "32 hexadecimal digits"),
            (
                b"zz0102030405060708090a0b0c0d0e0f",
                "not a hexadecimal digit",
            ),
            (b"\xff\xfe", "hexadecimal"),
            (b"00000000000000000000000000000000", "--insecure"),
        ] {
            std::fs::write(&path, text).unwrap();
            let e = read_key_file(&path).unwrap_err().to_string();
            assert!(e.contains(what) && e.contains("bad.key"), "{e}");
        }
        let e = choose(None, false, "x").unwrap_err().to_string();
        assert!(e.contains("--key FILE") && e.contains("--insecure"), "{e}");
        assert!(choose(Some(&path), true, "x").is_err());
        assert_eq!(choose(None, true, "x").unwrap(), Key::INSECURE);
        assert!(
            read_key_file(&dir.path().join("missing"))
                .unwrap_err()
                .to_string()
                .contains("missing")
        );
    }

    #[test]
    fn epochs_are_never_zero_and_nonces_differ() {
        assert_ne!(random_epoch().unwrap(), 0);
        assert_ne!(random_nonce().unwrap(), random_nonce().unwrap());
    }
}
