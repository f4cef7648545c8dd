//! Two flash pages in a file, holding the car's persisted state (learner, session, generation
//! and dedupe windows).
//!
//! The car keeps its state in two pages of flash and writes them alternately: a write always
//! goes to the page that does *not* hold the newest good state, so a write torn by a reset or a
//! corrupted page never loses the last good state. On start the newest page that passes every
//! check wins.
//!
//! The file is [`FILE_SIZE`] bytes: a [`HEADER_SIZE`]-byte header (the emulation's, not the
//! flash's: magic `b"CFWFLASH"`, format version `u16` = 3, page size `u16`, page count `u16`,
//! two bytes `0xFF`), then the two pages. [`FlashStore::open`] refuses an existing file that is
//! not such an image (another size, another header) and leaves it untouched, unless asked to
//! initialise it ([`Open::Initialise`], `hil_mock serve --init-flash`); a file that does not
//! exist is created erased.
//!
//! Page layout, little-endian, [`PAGE_SIZE`] bytes, erased bytes are `0xFF`:
//!
//! | bytes | content |
//! |---|---|
//! | 0..4 | magic `b"CFW3"` |
//! | 4..8 | write count `u32`, one more than the previous write's |
//! | 8..10 | payload length `n` |
//! | 10..10+n | the payload: a protocol envelope (version, postcard, CRC-16) of a [`Persisted`]: session, generation, learner snapshot, feedback dedupe windows (at most [`PERSISTED_MAX_SIZE`] bytes) |
//! | 10+n..14+n | CRC-32/ISO-HDLC of bytes 0..10+n |
//!
//! A page is good when the magic, the length, both CRCs, the envelope's version and the
//! snapshot's own checks ([`Learner::restore`]) all pass. (Format history: `CFW1` pages held a
//! bare `LearnerSnapshot`, `CFW2` pages a state without generation in a headerless file.)
//!
//! [`FlashStore`] implements [`Persist`], so a [`protocol::car::CarNode`] writes through it.

use std::fs::{File, OpenOptions};
use std::io::{Read, Seek, SeekFrom, Write};
use std::path::{Path, PathBuf};

use firmware_core::Learner;
use protocol::car::{PERSISTED_MAX_SIZE, Persist, Persisted};

/// Size of one page.
pub const PAGE_SIZE: usize = 512;

/// Size of the file's header.
pub const HEADER_SIZE: usize = 16;

/// Size of a flash image file: the header and two pages.
pub const FILE_SIZE: usize = HEADER_SIZE + 2 * PAGE_SIZE;

/// The file header of an image.
const FILE_HEADER: [u8; HEADER_SIZE] = {
    let mut h = [0xFF; HEADER_SIZE];
    let magic = *b"CFWFLASH";
    let mut i = 0;
    while i < 8 {
        h[i] = magic[i];
        i += 1;
    }
    let version = 3u16.to_le_bytes();
    let page = (PAGE_SIZE as u16).to_le_bytes();
    let pages = 2u16.to_le_bytes();
    h[8] = version[0];
    h[9] = version[1];
    h[10] = page[0];
    h[11] = page[1];
    h[12] = pages[0];
    h[13] = pages[1];
    h
};

const MAGIC: [u8; 4] = *b"CFW3";
const HEADER: usize = 10;
const CRC32: crc::Crc<u32> = crc::Crc::<u32>::new(&crc::CRC_32_ISO_HDLC);
const MAX_PAYLOAD: usize = PAGE_SIZE - HEADER - 4;

const _: () = assert!(
    PERSISTED_MAX_SIZE <= MAX_PAYLOAD,
    "the largest persisted state fits a page"
);

/// Why the store failed. Nothing already stored is lost by a failure.
#[derive(Debug, thiserror::Error)]
pub enum FlashError {
    /// Reading or writing the backing file failed.
    #[error("flash file {path}: {error}")]
    Io {
        /// The backing file.
        path: PathBuf,
        /// What the OS said (in the message, so not a `source`: a chain of causes prints it
        /// once).
        error: std::io::Error,
    },
    /// The state does not fit in a page (cannot happen: checked at compile time).
    #[error("state does not fit in a {PAGE_SIZE}-byte page")]
    TooLarge,
    /// The file exists and is not a flash image; it was left untouched.
    #[error(
        "{path} is not a flash image ({reason}); it was left untouched. Give another file, or \
         --init-flash to overwrite it with an erased image"
    )]
    NotAnImage {
        /// The file.
        path: PathBuf,
        /// What is wrong with it.
        reason: String,
    },
}

/// How [`FlashStore::open`] treats an existing file.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Open {
    /// Use it if it is a flash image; refuse it otherwise. A missing file is created erased.
    Existing,
    /// Erase it into a flash image whatever it holds (`--init-flash`).
    Initialise,
}

/// What a page held when the store was opened.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PageStatus {
    /// Erased (all `0xFF`) or never written.
    Empty,
    /// A good snapshot of this generation.
    Good(u32),
    /// Written but failing a check: torn, corrupted, or of an unknown format.
    Corrupt,
}

/// The state restored from the newest good page.
#[derive(Clone, Debug, PartialEq)]
pub struct Restored {
    /// The learner, continuing where the snapshot left it.
    pub learner: Learner,
    /// Everything persisted (session, generation, snapshot, dedupe windows).
    pub state: Persisted,
    /// The page's write count.
    pub generation: u32,
    /// The page it came from (0 or 1).
    pub page: usize,
}

/// The two-page store over a file.
#[derive(Debug)]
pub struct FlashStore {
    file: File,
    path: PathBuf,
    /// Page and generation of the newest good snapshot.
    newest: Option<(usize, u32)>,
    pages: [PageStatus; 2],
}

fn decode_page(page: &[u8]) -> Result<(u32, Learner, Persisted), PageStatus> {
    if page.iter().all(|&b| b == 0xFF) {
        return Err(PageStatus::Empty);
    }
    if page[..4] != MAGIC {
        return Err(PageStatus::Corrupt);
    }
    let generation = u32::from_le_bytes([page[4], page[5], page[6], page[7]]);
    let n = u16::from_le_bytes([page[8], page[9]]) as usize;
    if n > MAX_PAYLOAD {
        return Err(PageStatus::Corrupt);
    }
    let stored = u32::from_le_bytes([
        page[HEADER + n],
        page[HEADER + n + 1],
        page[HEADER + n + 2],
        page[HEADER + n + 3],
    ]);
    if CRC32.checksum(&page[..HEADER + n]) != stored {
        return Err(PageStatus::Corrupt);
    }
    let state: Persisted =
        protocol::open(&page[HEADER..HEADER + n]).map_err(|_| PageStatus::Corrupt)?;
    let learner = Learner::restore(&state.snapshot).map_err(|_| PageStatus::Corrupt)?;
    Ok((generation, learner, state))
}

fn encode_page(generation: u32, state: &Persisted) -> Result<[u8; PAGE_SIZE], FlashError> {
    let mut page = [0xFFu8; PAGE_SIZE];
    let n = protocol::seal(state, &mut page[HEADER..HEADER + MAX_PAYLOAD])
        .map_err(|_| FlashError::TooLarge)?
        .len();
    page[..4].copy_from_slice(&MAGIC);
    page[4..8].copy_from_slice(&generation.to_le_bytes());
    page[8..10].copy_from_slice(&(n as u16).to_le_bytes());
    let crc = CRC32.checksum(&page[..HEADER + n]);
    page[HEADER + n..HEADER + n + 4].copy_from_slice(&crc.to_le_bytes());
    Ok(page)
}

/// Why `bytes` (a whole file) is not a flash image, if it is not.
pub fn image_problem(bytes: &[u8]) -> Option<String> {
    if bytes.len() != FILE_SIZE {
        return Some(format!("{} bytes, an image is {FILE_SIZE}", bytes.len()));
    }
    if bytes[..HEADER_SIZE] != FILE_HEADER {
        return Some("its header is not a car flash image's".into());
    }
    None
}

/// The two pages' states decoded from an image's bytes (`FILE_SIZE` bytes, header checked).
/// Total: any bytes give a status per page, never a panic.
pub fn decode_pages(image: &[u8]) -> ([PageStatus; 2], Option<Restored>) {
    let mut pages = [PageStatus::Empty; 2];
    let mut best: Option<Restored> = None;
    for (i, status) in pages.iter_mut().enumerate() {
        let start = HEADER_SIZE + i * PAGE_SIZE;
        let Some(page) = image.get(start..start + PAGE_SIZE) else {
            continue;
        };
        match decode_page(page) {
            Ok((generation, learner, state)) => {
                *status = PageStatus::Good(generation);
                if best.as_ref().is_none_or(|b| generation > b.generation) {
                    best = Some(Restored {
                        learner,
                        state,
                        generation,
                        page: i,
                    });
                }
            }
            Err(s) => *status = s,
        }
    }
    (pages, best)
}

impl FlashStore {
    /// Opens the store at `path` (creating an erased image if there is no file) and restores
    /// the newest good state, if any. An existing file that is not an image is refused and left
    /// untouched, unless `open` is [`Open::Initialise`].
    pub fn open(
        path: impl AsRef<Path>,
        open: Open,
    ) -> Result<(Self, Option<Restored>), FlashError> {
        let path = path.as_ref().to_path_buf();
        let io = |error| FlashError::Io {
            path: path.clone(),
            error,
        };
        let mut file = OpenOptions::new()
            .read(true)
            .write(true)
            .create(true)
            .truncate(false)
            .open(&path)
            .map_err(io)?;
        let mut bytes = Vec::with_capacity(FILE_SIZE);
        file.read_to_end(&mut bytes).map_err(io)?;
        let fresh = bytes.is_empty();
        if let Some(reason) = image_problem(&bytes)
            && !fresh
            && open == Open::Existing
        {
            return Err(FlashError::NotAnImage { path, reason });
        }
        if fresh || open == Open::Initialise {
            bytes = vec![0xFF; FILE_SIZE];
            bytes[..HEADER_SIZE].copy_from_slice(&FILE_HEADER);
            file.set_len(0).map_err(io)?;
            file.seek(SeekFrom::Start(0)).map_err(io)?;
            file.write_all(&bytes).map_err(io)?;
            file.sync_data().map_err(io)?;
        }
        let (pages, best) = decode_pages(&bytes);
        let store = Self {
            file,
            path,
            newest: best.as_ref().map(|b| (b.page, b.generation)),
            pages,
        };
        Ok((store, best))
    }

    /// What each page held when the store was opened.
    pub fn pages(&self) -> [PageStatus; 2] {
        self.pages
    }

    /// The generation of the newest good snapshot, if any.
    pub fn generation(&self) -> Option<u32> {
        self.newest.map(|(_, g)| g)
    }

    /// Writes `state` to the page not holding the newest good one, flushes it to disk, and
    /// returns its generation.
    pub fn save(&mut self, state: &Persisted) -> Result<u32, FlashError> {
        let (page, generation) = match self.newest {
            Some((p, g)) => (1 - p, g.wrapping_add(1)),
            None => (0, 1),
        };
        let bytes = encode_page(generation, state)?;
        let io = |error| FlashError::Io {
            path: self.path.clone(),
            error,
        };
        self.file
            .seek(SeekFrom::Start((HEADER_SIZE + page * PAGE_SIZE) as u64))
            .map_err(io)?;
        self.file.write_all(&bytes).map_err(io)?;
        self.file.sync_data().map_err(io)?;
        self.newest = Some((page, generation));
        self.pages[page] = PageStatus::Good(generation);
        Ok(generation)
    }
}

impl Persist for FlashStore {
    type Error = FlashError;

    fn persist(&mut self, state: &Persisted) -> Result<(), FlashError> {
        self.save(state).map(|_| ())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use firmware_core::{LearnerParams, OnlineLearner};
    use protocol::delivery::FeedbackReceiver;

    fn learner_after(steps: usize) -> Learner {
        let mut l = Learner::new(LearnerParams::default().check().unwrap());
        for i in 0..steps {
            l.step(&[i as f32, -1.0, 0.5, 0.0, 2.0, -3.0]).unwrap();
        }
        l
    }

    fn state_after(steps: usize) -> Persisted {
        Persisted {
            session: Some(steps as u8),
            generation: steps as u32,
            snapshot: learner_after(steps).snapshot(),
            receiver: FeedbackReceiver::new(),
        }
    }

    fn open(path: &Path) -> (FlashStore, Option<Restored>) {
        FlashStore::open(path, Open::Existing).unwrap()
    }

    #[test]
    fn a_snapshot_fits_in_a_page_with_room() {
        let page = encode_page(1, &state_after(3)).unwrap();
        let n = u16::from_le_bytes([page[8], page[9]]) as usize;
        assert!(n <= PERSISTED_MAX_SIZE, "payload {n} bytes");
    }

    #[test]
    fn saves_alternate_pages_and_the_newest_wins() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("flash.bin");
        let (mut store, restored) = open(&path);
        assert!(restored.is_none());
        assert_eq!(store.pages(), [PageStatus::Empty; 2]);
        assert_eq!(std::fs::metadata(&path).unwrap().len(), FILE_SIZE as u64);
        for k in 1..=5 {
            assert_eq!(store.save(&state_after(k)).unwrap(), k as u32);
        }
        drop(store);
        let (store, restored) = open(&path);
        let r = restored.unwrap();
        assert_eq!((r.generation, r.page), (5, 0));
        assert_eq!(r.learner, learner_after(5));
        assert_eq!(r.state, state_after(5));
        assert_eq!(store.pages(), [PageStatus::Good(5), PageStatus::Good(4)]);
    }

    #[test]
    fn a_torn_or_corrupt_page_falls_back_to_the_other() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("flash.bin");
        let (mut store, _) = open(&path);
        store.save(&state_after(1)).unwrap(); // page 0, write 1
        store.save(&state_after(2)).unwrap(); // page 1, write 2
        drop(store);
        // Flip one byte in the middle of page 1's payload.
        let mut bytes = std::fs::read(&path).unwrap();
        bytes[HEADER_SIZE + PAGE_SIZE + 40] ^= 0x10;
        std::fs::write(&path, &bytes).unwrap();
        let (store, restored) = open(&path);
        assert_eq!(store.pages(), [PageStatus::Good(1), PageStatus::Corrupt]);
        let r = restored.unwrap();
        assert_eq!((r.generation, r.learner), (1, learner_after(1)));
        // A torn write: page 1 erased from byte 30 on.
        for b in &mut bytes[HEADER_SIZE + PAGE_SIZE + 30..] {
            *b = 0xFF;
        }
        std::fs::write(&path, &bytes).unwrap();
        let (mut store, restored) = open(&path);
        assert_eq!(restored.unwrap().learner, learner_after(1));
        // The next save overwrites the bad page, never the good one.
        assert_eq!(store.save(&state_after(3)).unwrap(), 2);
        let (store, restored) = open(&path);
        assert_eq!(store.pages(), [PageStatus::Good(1), PageStatus::Good(2)]);
        assert_eq!(restored.unwrap().learner, learner_after(3));
    }

    #[test]
    fn both_pages_corrupt_restore_nothing() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("flash.bin");
        let (mut store, _) = open(&path);
        store.save(&state_after(1)).unwrap();
        store.save(&state_after(2)).unwrap();
        drop(store);
        let mut bytes = std::fs::read(&path).unwrap();
        bytes[HEADER_SIZE + 40] ^= 1;
        bytes[HEADER_SIZE + PAGE_SIZE + 40] ^= 1;
        std::fs::write(&path, &bytes).unwrap();
        let (store, restored) = open(&path);
        assert!(restored.is_none());
        assert_eq!(store.pages(), [PageStatus::Corrupt; 2]);
    }

    #[test]
    fn a_file_that_is_not_an_image_is_refused_and_left_untouched() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("precious.bin");
        let mut state = 0x1234_5678u32;
        let random: Vec<u8> = (0..100_000)
            .map(|_| {
                state ^= state << 13;
                state ^= state >> 17;
                state ^= state << 5;
                state as u8
            })
            .collect();
        let cases = [
            random.clone(),
            vec![0u8; 7],
            vec![0x55; FILE_SIZE],
            vec![0xFF; 2 * 256],
            b"CFW1\xff\xff\xff\xff\xff\xff".to_vec(),
        ];
        for garbage in cases {
            std::fs::write(&path, &garbage).unwrap();
            let err = FlashStore::open(&path, Open::Existing).unwrap_err();
            assert!(matches!(err, FlashError::NotAnImage { .. }), "{err}");
            assert!(err.to_string().contains("--init-flash"), "{err}");
            assert_eq!(std::fs::read(&path).unwrap(), garbage, "untouched");
        }
        // Told to, it initialises the file.
        let (_, restored) = FlashStore::open(&path, Open::Initialise).unwrap();
        assert!(restored.is_none());
        assert_eq!(image_problem(&std::fs::read(&path).unwrap()), None);
        let _ = open(&path);
    }

    #[test]
    fn an_unwritable_path_is_a_clear_error() {
        let err = FlashStore::open("/nonexistent-dir/flash.bin", Open::Existing).unwrap_err();
        assert!(
            err.to_string().contains("/nonexistent-dir/flash.bin"),
            "{err}"
        );
    }
}
