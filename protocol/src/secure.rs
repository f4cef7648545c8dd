//! Authenticated messages, AUTOSAR SecOC style: a truncated AES-128-CMAC over the message and
//! a freshness value, checked before the message has any effect.
//!
//! # The secured PDU
//!
//! Every message on the wire is
//!
//! ```text
//! [version: u8 = 3][postcard payload][freshness: u8][MAC: 4 bytes]
//! ```
//!
//! * The **freshness value** is 64 bits, `epoch (u32) ‖ counter (u32)`. The *epoch* is the car's:
//!   a number it takes anew at every start (a random number, or a boot counter kept in flash)
//!   and never 0. The *counter* counts the messages of one direction within the epoch; each
//!   direction has its own. Only the counter's low byte travels; the receiver takes the counter
//!   nearest to the highest it accepted with that low byte (within ±128).
//! * The **MAC** is AES-128-CMAC (NIST SP 800-38B) with the car's 128-bit key over
//!   `CAN id (u16, big-endian) ‖ version ‖ payload ‖ freshness value (8 bytes, big-endian)`,
//!   truncated to its first [`MAC_LEN`] bytes. The CAN identifier names the stream and the
//!   direction, so a message cannot be moved to another stream or reflected back; the epoch
//!   binds it to one start of the car.
//! * The CAN frames' own CRC catches transmission errors; the MAC replaces the envelope's CRC-16.
//!
//! # Checks, in order
//!
//! Length and version; the payload decodes (total, no effect); the MAC verifies (constant
//! time) with the freshness value the receiver reconstructs; the counter is fresh: above the
//! highest accepted, or within the last [`REPLAY_WINDOW`] and never accepted before (a sliding
//! bitmap, as IPsec's anti-replay window: reordered messages are accepted once, copies never).
//! A refused message is counted ([`RefusalStats`]) and has no other effect.
//!
//! # Synchronisation: hello and welcome
//!
//! The host learns the car's epoch and counters from a handshake: it sends
//! [`Hello`] with a fresh random nonce, the epoch it believes the car is
//! in and its own next counter; the car answers [`Welcome`] with the
//! nonce, its epoch, the counter of the welcome itself, the next host counter it accepts and its
//! status. The hello is authenticated under the fixed freshness value 0 (epoch 0 is never a
//! car's), so it can be replayed: its only effect is a welcome, and moving the car's window
//! forward to a counter the host really reached. The welcome is fresh because it repeats the
//! nonce, and current because no newer message of the car in its epoch came before it (one
//! that such messages overtook says what the car held before them, and is refused). A car
//! that restarts takes a new epoch, so nothing recorded before its restart is
//! accepted after it, and the host notices the restart: its messages go unanswered until it says
//! hello again, and the welcome carries the new epoch and what the car holds.
//!
//! ```
//! use protocol::message::Message;
//! use protocol::secure::{CarSecurity, Endpoint, HostSecurity, Key};
//! use protocol::stream::{Direction, Stream};
//!
//! let key = Key::from_hex("000102030405060708090a0b0c0d0e0f").unwrap();
//! let mut car = CarSecurity::new(&key, 7);
//! let mut host = HostSecurity::new(&key);
//! let stream = Stream::for_kind(Message::Heartbeat.kind(), Direction::HostToCar).unwrap();
//! let mut buf = [0u8; 16];
//! // Before a welcome the host knows no epoch: only a hello goes out.
//! assert!(host.seal(&Message::Heartbeat, stream, &mut buf).is_err());
//! ```

use core::fmt;

use aes::Aes128Enc;
use aes::cipher::{Block, BlockCipherEncrypt, KeyInit};

use crate::envelope::{EnvelopeError, PROTOCOL_VERSION};
use crate::message::{DecodeError, Hello, Message, MessageKind, NONCE_LEN, Welcome};
use crate::stream::Stream;

/// Bytes of a key.
pub const KEY_LEN: usize = 16;

/// Bytes of the truncated MAC on the wire.
pub const MAC_LEN: usize = 4;

/// Bytes a secured PDU adds to the postcard payload: version, freshness byte, MAC.
pub const SECURED_OVERHEAD: usize = 2 + MAC_LEN;

/// How many counters below the highest accepted one a receiver still accepts once (reordered
/// messages).
pub const REPLAY_WINDOW: u32 = 64;

const _: () = assert!(
    REPLAY_WINDOW < 128,
    "the window lies within the reach of the freshness byte"
);

/// A car's 128-bit key. `Debug` does not print it.
#[derive(Clone, PartialEq, Eq)]
pub struct Key([u8; KEY_LEN]);

impl fmt::Debug for Key {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        if self.is_insecure() {
            f.write_str("Key(insecure all-zero key)")
        } else {
            f.write_str("Key(..)")
        }
    }
}

/// Why text is not a key.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
#[non_exhaustive]
pub enum KeyError {
    /// Not 32 hexadecimal digits (this many characters, blanks around them left out).
    Length(usize),
    /// The character at this position is not a hexadecimal digit.
    NotHex(usize),
}

impl fmt::Display for KeyError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            KeyError::Length(n) => write!(
                f,
                "a key is {} hexadecimal digits, found {n} characters",
                2 * KEY_LEN
            ),
            KeyError::NotHex(i) => write!(f, "character {i} of the key is not a hexadecimal digit"),
        }
    }
}

impl core::error::Error for KeyError {}

impl Key {
    /// The all-zero key of `--insecure`: publicly known, so it authenticates nothing. Messages
    /// still carry MACs and freshness (the same code runs), which only catch accidents.
    pub const INSECURE: Key = Key([0; KEY_LEN]);

    /// A key of these bytes.
    pub const fn new(bytes: [u8; KEY_LEN]) -> Self {
        Self(bytes)
    }

    /// The key's bytes.
    pub const fn bytes(&self) -> &[u8; KEY_LEN] {
        &self.0
    }

    /// Whether this is [`Key::INSECURE`].
    pub fn is_insecure(&self) -> bool {
        self.0 == [0; KEY_LEN]
    }

    /// The key written as 32 hexadecimal digits (blanks around them allowed; upper or lower
    /// case), the format of a key file.
    pub fn from_hex(text: &str) -> Result<Self, KeyError> {
        let digits = text.trim().as_bytes();
        if digits.len() != 2 * KEY_LEN {
            return Err(KeyError::Length(digits.len()));
        }
        let mut key = [0u8; KEY_LEN];
        for (i, d) in digits.iter().enumerate() {
            let v = match d {
                b'0'..=b'9' => d - b'0',
                b'a'..=b'f' => d - b'a' + 10,
                b'A'..=b'F' => d - b'A' + 10,
                _ => return Err(KeyError::NotHex(i)),
            };
            key[i / 2] |= v << if i % 2 == 0 { 4 } else { 0 };
        }
        Ok(Self(key))
    }

    /// The key as 32 lower-case hexadecimal digits.
    pub fn to_hex(&self) -> [u8; 2 * KEY_LEN] {
        const DIGITS: &[u8; 16] = b"0123456789abcdef";
        let mut out = [0u8; 2 * KEY_LEN];
        for (i, b) in self.0.iter().enumerate() {
            out[2 * i] = DIGITS[(b >> 4) as usize];
            out[2 * i + 1] = DIGITS[(b & 0x0F) as usize];
        }
        out
    }
}

/// A 64-bit freshness value: the car's epoch and a message counter.
#[derive(Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash, Debug)]
pub struct Freshness {
    /// The car's epoch (never 0 for a car).
    pub epoch: u32,
    /// The counter of one direction in that epoch.
    pub counter: u32,
}

impl Freshness {
    /// The freshness value of every hello: epoch 0, counter 0.
    pub const HELLO: Freshness = Freshness {
        epoch: 0,
        counter: 0,
    };

    /// Big-endian bytes, as the MAC covers them.
    pub const fn to_be_bytes(self) -> [u8; 8] {
        let e = self.epoch.to_be_bytes();
        let c = self.counter.to_be_bytes();
        [e[0], e[1], e[2], e[3], c[0], c[1], c[2], c[3]]
    }
}

/// AES-128-CMAC (NIST SP 800-38B, RFC 4493) keyed once: computes and verifies truncated MACs.
///
/// The AES key schedule and both CMAC subkeys are derived here, once per key, and every message
/// then costs its blocks and nothing more: the `cmac` crate derives the subkeys again at every
/// finalisation (one more AES block per message) and its keyed state is copied for every message.
/// The MAC input `CAN id ‖ body ‖ freshness` is read in place, never copied into a buffer.
/// Checked against RFC 4493's examples and, on random keys and messages, against RustCrypto's
/// `cmac` (tests).
#[derive(Clone)]
pub struct Authenticator {
    cipher: Aes128Enc,
    /// `K1 = dbl(AES_K(0))`: masks a complete last block.
    k1: [u8; 16],
    /// `K2 = dbl(K1)`: masks a padded last block.
    k2: [u8; 16],
}

impl fmt::Debug for Authenticator {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str("Authenticator(AES-128-CMAC)")
    }
}

/// Doubling in GF(2^128) as CMAC defines it: a shift left by one bit of the big-endian block,
/// and the constant 0x87 into the last byte when the shifted-out bit was set.
fn dbl(block: [u8; 16]) -> [u8; 16] {
    let v = u128::from_be_bytes(block);
    let carry = (v >> 127) as u8;
    let mut out = (v << 1).to_be_bytes();
    // Branch-free: the key material decides no branch.
    out[15] ^= 0x87 & carry.wrapping_neg();
    out
}

impl Authenticator {
    /// An authenticator with `key`: the AES key schedule and the CMAC subkeys computed once.
    pub fn new(key: &Key) -> Self {
        let cipher = Aes128Enc::new(&key.0.into());
        let mut l = Block::<Aes128Enc>::default();
        cipher.encrypt_block(&mut l);
        let k1 = dbl(l.into());
        let k2 = dbl(k1);
        Self { cipher, k1, k2 }
    }

    /// The CMAC of the concatenation of `parts`, read in place.
    fn cmac(&self, parts: [&[u8]; 3]) -> [u8; 16] {
        // The block being chained, and how many of its bytes the message filled. A full block
        // is encrypted only when another byte follows: the last block is masked first.
        let mut x = Block::<Aes128Enc>::default();
        let mut filled = 0usize;
        for part in parts {
            for &b in part {
                if filled == 16 {
                    self.cipher.encrypt_block(&mut x);
                    filled = 0;
                }
                x[filled] ^= b;
                filled += 1;
            }
        }
        let mask = if filled == 16 {
            &self.k1
        } else {
            x[filled] ^= 0x80;
            &self.k2
        };
        for (b, m) in x.iter_mut().zip(mask) {
            *b ^= m;
        }
        self.cipher.encrypt_block(&mut x);
        x.into()
    }

    /// The full 16-byte CMAC of `body` (version and payload) on `stream` with `fv`.
    pub fn full_tag(&self, stream: Stream, body: &[u8], fv: Freshness) -> [u8; 16] {
        self.cmac([&stream.raw_id().to_be_bytes(), body, &fv.to_be_bytes()])
    }

    /// The truncated MAC: the first [`MAC_LEN`] bytes of [`Authenticator::full_tag`].
    pub fn tag(&self, stream: Stream, body: &[u8], fv: Freshness) -> [u8; MAC_LEN] {
        let t = self.full_tag(stream, body, fv);
        [t[0], t[1], t[2], t[3]]
    }

    /// Whether `tag` is the truncated MAC (compared in constant time: every byte is looked at,
    /// whatever the first difference).
    pub fn verify(&self, stream: Stream, body: &[u8], fv: Freshness, tag: &[u8]) -> bool {
        if tag.len() != MAC_LEN {
            return false;
        }
        let expected = self.tag(stream, body, fv);
        let mut difference = 0u8;
        for (a, b) in expected.iter().zip(tag) {
            difference |= a ^ b;
        }
        core::hint::black_box(difference) == 0
    }
}

/// Writes `msg` as a secured PDU for `stream` with freshness `fv` into `buf`.
pub fn seal_pdu<'b>(
    msg: &Message,
    stream: Stream,
    auth: &Authenticator,
    fv: Freshness,
    buf: &'b mut [u8],
) -> Result<&'b [u8], EnvelopeError> {
    if buf.len() < SECURED_OVERHEAD {
        return Err(EnvelopeError::BufferTooSmall);
    }
    buf[0] = PROTOCOL_VERSION;
    let room = buf.len() - SECURED_OVERHEAD;
    let n = postcard::to_slice(msg, &mut buf[1..1 + room])
        .map_err(|_| EnvelopeError::BufferTooSmall)?
        .len();
    buf[1 + n] = fv.counter as u8;
    let tag = auth.tag(stream, &buf[..1 + n], fv);
    buf[2 + n..2 + n + MAC_LEN].copy_from_slice(&tag);
    Ok(&buf[..2 + n + MAC_LEN])
}

/// A checked view of a secured PDU: after [`SecuredPdu::new_checked`] no accessor panics.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
pub struct SecuredPdu<'a> {
    bytes: &'a [u8],
}

impl<'a> SecuredPdu<'a> {
    /// Checks the length (a version, a variant number, the freshness byte and the MAC at least)
    /// and the version.
    pub fn new_checked(bytes: &'a [u8]) -> Result<Self, EnvelopeError> {
        if bytes.len() < SECURED_OVERHEAD + 1 {
            return Err(EnvelopeError::Truncated);
        }
        if bytes[0] != PROTOCOL_VERSION {
            return Err(EnvelopeError::Version(bytes[0]));
        }
        Ok(Self { bytes })
    }

    /// Version and payload: what the MAC covers besides the CAN id and the freshness value.
    pub fn body(&self) -> &'a [u8] {
        &self.bytes[..self.bytes.len() - 1 - MAC_LEN]
    }

    /// The postcard payload.
    pub fn payload(&self) -> &'a [u8] {
        &self.body()[1..]
    }

    /// The low byte of the freshness counter.
    pub fn freshness_byte(&self) -> u8 {
        self.bytes[self.bytes.len() - 1 - MAC_LEN]
    }

    /// The truncated MAC.
    pub fn tag(&self) -> &'a [u8] {
        &self.bytes[self.bytes.len() - MAC_LEN..]
    }

    /// The kind its payload's first byte (postcard's variant tag) names, if any: the one byte of
    /// a PDU read before its MAC verifies, since it says which freshness value the MAC covers (a
    /// hello's fixed one, a welcome's own).
    pub fn kind(&self) -> Option<MessageKind> {
        MessageKind::from_tag(self.payload()[0])
    }

    /// The payload decoded ([`Message::decode_payload`]).
    pub fn message(&self) -> Result<Message, DecodeError> {
        Message::decode_payload(self.payload())
    }
}

/// Why an authentic-looking PDU was refused.
#[derive(Clone, Copy, PartialEq, Eq, Hash, Debug)]
#[non_exhaustive]
pub enum Refusal {
    /// The MAC does not verify: another key, a forgery, a corrupted frame, or a message of
    /// another epoch.
    Mac,
    /// Its counter was accepted before: a copy.
    Replayed,
    /// Its counter is older than the replay window; or the welcome answers no hello of ours, or
    /// newer messages of the car in its epoch came before it (its status is out of date).
    Stale,
    /// The host has no epoch yet (no welcome): only a welcome can be checked.
    Unsynced,
    /// The car has no key: it accepts nothing.
    Unkeyed,
}

impl fmt::Display for Refusal {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            Refusal::Mac => "MAC does not verify",
            Refusal::Replayed => "freshness counter already accepted (a copy)",
            Refusal::Stale => {
                "freshness older than the replay window, or a welcome out of date or to no hello"
            }
            Refusal::Unsynced => "no epoch yet (no welcome)",
            Refusal::Unkeyed => "no key installed",
        })
    }
}

/// Refused PDUs, by reason (saturating counters).
#[derive(Clone, Copy, PartialEq, Eq, Hash, Debug, Default)]
pub struct RefusalStats {
    /// MAC failures.
    pub mac: u32,
    /// Copies of accepted messages.
    pub replayed: u32,
    /// Too old, or a welcome to another hello.
    pub stale: u32,
    /// Before the first welcome (host) or without a key (car).
    pub unsynced: u32,
}

impl RefusalStats {
    const ZERO: Self = Self {
        mac: 0,
        replayed: 0,
        stale: 0,
        unsynced: 0,
    };

    /// All refusals.
    pub const fn total(&self) -> u32 {
        self.mac
            .saturating_add(self.replayed)
            .saturating_add(self.stale)
            .saturating_add(self.unsynced)
    }

    fn count(&mut self, r: Refusal) {
        let c = match r {
            Refusal::Mac => &mut self.mac,
            Refusal::Replayed => &mut self.replayed,
            Refusal::Stale => &mut self.stale,
            Refusal::Unsynced | Refusal::Unkeyed => &mut self.unsynced,
        };
        *c = c.saturating_add(1);
    }
}

/// A receiver's window over one direction's counters: the highest accepted, and which of the
/// [`REPLAY_WINDOW`] below it were accepted.
#[derive(Clone, Copy, PartialEq, Eq, Debug, Default)]
pub struct ReplayWindow {
    highest: Option<u32>,
    /// Bit `k`: counter `highest − k` was accepted.
    seen: u64,
}

impl ReplayWindow {
    /// A window that accepted nothing.
    pub const fn new() -> Self {
        Self {
            highest: None,
            seen: 0,
        }
    }

    /// The highest counter accepted.
    pub const fn highest(&self) -> Option<u32> {
        self.highest
    }

    /// The counter after the highest accepted (0 if none).
    pub const fn next(&self) -> u32 {
        match self.highest {
            Some(h) => h.saturating_add(1),
            None => 0,
        }
    }

    /// The counter whose low byte is `low` nearest to the highest accepted (within −128..+127);
    /// `low` itself before anything was accepted.
    pub fn resolve(&self, low: u8) -> u32 {
        match self.highest {
            None => low as u32,
            Some(h) => {
                let delta = low.wrapping_sub(h as u8) as i8 as i32;
                if delta < 0 && delta.unsigned_abs() > h {
                    // Below counter 0: the other candidate, ahead.
                    h + (delta + 256) as u32
                } else {
                    h.wrapping_add(delta as u32)
                }
            }
        }
    }

    /// Whether `counter` may be accepted: newer than the highest, or within the window and not
    /// accepted yet.
    pub fn check(&self, counter: u32) -> Result<(), Refusal> {
        match self.highest {
            None => Ok(()),
            Some(h) if counter > h => Ok(()),
            Some(h) => {
                let back = h - counter;
                if back >= REPLAY_WINDOW {
                    Err(Refusal::Stale)
                } else if self.seen >> back & 1 == 1 {
                    Err(Refusal::Replayed)
                } else {
                    Ok(())
                }
            }
        }
    }

    /// Records `counter` as accepted (after [`ReplayWindow::check`]).
    pub fn accept(&mut self, counter: u32) {
        match self.highest {
            Some(h) if counter <= h => {
                let back = h - counter;
                if back < REPLAY_WINDOW {
                    self.seen |= 1 << back;
                }
            }
            Some(h) => {
                let shift = counter - h;
                self.seen = if shift >= 64 { 0 } else { self.seen << shift } | 1;
                self.highest = Some(counter);
            }
            None => {
                self.highest = Some(counter);
                self.seen = 1;
            }
        }
    }

    /// Moves the window so that nothing below `next` is newer than the highest: counters the
    /// sender reached (told by an authenticated hello or welcome) but the receiver never saw.
    pub fn advance_to(&mut self, next: u32) {
        if next > self.next() {
            let h = next - 1;
            let shift = self.highest.map_or(64, |old| h - old);
            self.seen = if shift >= 64 { 0 } else { self.seen << shift };
            self.highest = Some(h);
        }
    }
}

/// Why a message could not be sealed.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
#[non_exhaustive]
pub enum SealError {
    /// The host has no epoch yet: say hello first.
    Unsynced,
    /// The car has no key.
    Unkeyed,
    /// The counter of this epoch is used up (2³² messages): a new epoch is needed (a restart of
    /// the car).
    Exhausted,
    /// The message does not fit the buffer.
    Encode(EnvelopeError),
}

impl fmt::Display for SealError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            SealError::Unsynced => f.write_str("no epoch yet: the host must say hello first"),
            SealError::Unkeyed => f.write_str("no key installed"),
            SealError::Exhausted => f.write_str("freshness counter used up in this epoch"),
            SealError::Encode(e) => write!(f, "encoding: {e}"),
        }
    }
}

impl core::error::Error for SealError {}

/// Why a received PDU gave no message.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
#[non_exhaustive]
pub enum OpenError {
    /// Too short or of another version; or authentic and fresh but its payload does not decode
    /// (only the key's holder can send one).
    Decode(DecodeError),
    /// Refused before it was decoded: authentication or freshness (a welcome, whose MAC covers
    /// the freshness value it carries, is decoded first).
    Refused(Refusal),
}

impl fmt::Display for OpenError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            OpenError::Decode(e) => e.fmt(f),
            OpenError::Refused(r) => write!(f, "refused: {r}"),
        }
    }
}

impl From<DecodeError> for OpenError {
    fn from(e: DecodeError) -> Self {
        OpenError::Decode(e)
    }
}

impl From<EnvelopeError> for OpenError {
    fn from(e: EnvelopeError) -> Self {
        OpenError::Decode(DecodeError::Envelope(e))
    }
}

/// The car's side: its key, its epoch, its own counter and the window over the host's.
#[derive(Clone, Debug)]
pub struct CarSecurity {
    auth: Option<Authenticator>,
    epoch: u32,
    next_tx: Option<u32>,
    rx: ReplayWindow,
    refused: RefusalStats,
    /// The message opened last carried the highest host counter yet.
    newest: bool,
}

impl Default for CarSecurity {
    fn default() -> Self {
        Self::unkeyed()
    }
}

impl CarSecurity {
    /// A car without a key: it refuses everything and sends nothing ([`CarSecurity::install`]).
    pub const fn unkeyed() -> Self {
        Self {
            auth: None,
            epoch: 1,
            next_tx: Some(0),
            rx: ReplayWindow::new(),
            refused: RefusalStats::ZERO,
            newest: false,
        }
    }

    /// Every byte zero (no key, epoch 0, no counter left): [`crate::car::CarNodeSlot`]'s
    /// storage, replaced by [`CarSecurity::unkeyed`] before the node is used.
    pub(crate) const BLANK: Self = Self {
        auth: None,
        epoch: 0,
        next_tx: None,
        rx: ReplayWindow::new(),
        refused: RefusalStats::ZERO,
        newest: false,
    };

    /// A car with `key` in `epoch` (0 is taken as 1: epoch 0 is the hello's).
    pub fn new(key: &Key, epoch: u32) -> Self {
        let mut s = Self::unkeyed();
        s.install(key, epoch);
        s
    }

    /// Installs `key` and starts `epoch` (0 is taken as 1): counters from 0, nothing accepted.
    /// Refusal counters are kept.
    pub fn install(&mut self, key: &Key, epoch: u32) {
        self.auth = Some(Authenticator::new(key));
        self.epoch = epoch.max(1);
        self.next_tx = Some(0);
        self.rx = ReplayWindow::new();
    }

    /// Whether a key is installed.
    pub fn is_keyed(&self) -> bool {
        self.auth.is_some()
    }

    /// The car's epoch.
    pub const fn epoch(&self) -> u32 {
        self.epoch
    }

    /// The counter the next message will carry.
    pub fn next_counter(&self) -> u32 {
        self.next_tx.unwrap_or(u32::MAX)
    }

    /// The next host counter the car accepts.
    pub const fn host_next(&self) -> u32 {
        self.rx.next()
    }

    /// Refused PDUs so far.
    pub const fn refusals(&self) -> RefusalStats {
        self.refused
    }

    /// Whether the message opened last carried a host counter above every one accepted before
    /// (not a hello, not a reordered or delayed message). Only such a message can have come
    /// first from the host itself: a genuine message that was lost on the way and is replayed
    /// later by another node is accepted once (it was never seen), but is not the newest, so a
    /// transport does not start trusting the replayer's address for it.
    pub const fn opened_newest(&self) -> bool {
        self.newest
    }

    /// Takes an authenticated hello: a host that reached a later counter in this epoch than the
    /// car saw moves the window up to it.
    pub fn on_hello(&mut self, hello: &Hello) {
        if hello.epoch == self.epoch {
            self.rx.advance_to(hello.counter);
        }
    }

    /// The welcome answering `hello`, with the car's `status` (to be sealed next, so that its
    /// counter is the one it names).
    pub fn welcome(&self, hello: &Hello, status: crate::message::CarStatus) -> Welcome {
        Welcome {
            nonce: hello.nonce,
            epoch: self.epoch,
            counter: self.next_counter(),
            host_next: self.host_next(),
            status,
            refused: self.refused.total(),
        }
    }

    fn refuse(&mut self, r: Refusal) -> OpenError {
        self.refused.count(r);
        OpenError::Refused(r)
    }
}

/// How the node's link layer seals and opens messages: [`CarSecurity`] and [`HostSecurity`].
pub trait Endpoint {
    /// Writes `msg` as a secured PDU for `stream` into `buf`, using the next counter.
    fn seal<'b>(
        &mut self,
        msg: &Message,
        stream: Stream,
        buf: &'b mut [u8],
    ) -> Result<&'b [u8], SealError>;

    /// Checks and decodes a PDU received on `stream`; a refusal is counted.
    fn open(&mut self, stream: Stream, pdu: &[u8]) -> Result<Message, OpenError>;
}

impl Endpoint for CarSecurity {
    fn seal<'b>(
        &mut self,
        msg: &Message,
        stream: Stream,
        buf: &'b mut [u8],
    ) -> Result<&'b [u8], SealError> {
        let auth = self.auth.as_ref().ok_or(SealError::Unkeyed)?;
        let counter = self.next_tx.ok_or(SealError::Exhausted)?;
        let fv = Freshness {
            epoch: self.epoch,
            counter,
        };
        let bytes = seal_pdu(msg, stream, auth, fv, buf).map_err(SealError::Encode)?;
        self.next_tx = counter.checked_add(1);
        Ok(bytes)
    }

    /// Authenticates before it parses: of a PDU whose MAC does not verify, nothing is decoded but
    /// the variant tag ([`SecuredPdu::kind`]), so a stranger's bytes never reach postcard's
    /// decoder. A PDU that verifies, is fresh and does not decode (only the key's holder can make
    /// one) is a decode error, and its counter is not taken.
    fn open(&mut self, stream: Stream, pdu: &[u8]) -> Result<Message, OpenError> {
        self.newest = false;
        let pdu = SecuredPdu::new_checked(pdu)?;
        let Some(auth) = &self.auth else {
            return Err(self.refuse(Refusal::Unkeyed));
        };
        if pdu.kind() == Some(MessageKind::Hello) {
            // Replayable by design: its only effects are a welcome and `on_hello`.
            if !auth.verify(stream, pdu.body(), Freshness::HELLO, pdu.tag()) {
                return Err(self.refuse(Refusal::Mac));
            }
            return Ok(pdu.message()?);
        }
        let counter = self.rx.resolve(pdu.freshness_byte());
        let fv = Freshness {
            epoch: self.epoch,
            counter,
        };
        if !auth.verify(stream, pdu.body(), fv, pdu.tag()) {
            return Err(self.refuse(Refusal::Mac));
        }
        if let Err(r) = self.rx.check(counter) {
            return Err(self.refuse(r));
        }
        let msg = pdu.message()?;
        self.newest = self.rx.highest().is_none_or(|h| counter > h);
        self.rx.accept(counter);
        Ok(msg)
    }
}

#[derive(Clone, Copy, Debug)]
struct Sync {
    epoch: u32,
    next_tx: Option<u32>,
    rx: ReplayWindow,
}

/// The host's side: its key, the car's epoch as the last welcome told it, its own counter and
/// the window over the car's.
#[derive(Clone, Debug)]
pub struct HostSecurity {
    auth: Authenticator,
    sync: Option<Sync>,
    nonce: Option<[u8; NONCE_LEN]>,
    refused: RefusalStats,
    /// The message opened last carried the highest car counter yet.
    newest: bool,
}

impl HostSecurity {
    /// A host with `key` that knows no epoch yet: it must say hello ([`HostSecurity::hello`]).
    pub fn new(key: &Key) -> Self {
        Self {
            auth: Authenticator::new(key),
            sync: None,
            nonce: None,
            refused: RefusalStats::ZERO,
            newest: false,
        }
    }

    /// A host that takes the car to have just started in `epoch` (both counters at 0), without a
    /// handshake: for tests and benchmarks that drive a fresh [`CarSecurity`] directly.
    pub fn assume_fresh_car(key: &Key, epoch: u32) -> Self {
        let mut s = Self::new(key);
        s.sync = Some(Sync {
            epoch: epoch.max(1),
            next_tx: Some(0),
            rx: ReplayWindow::new(),
        });
        s
    }

    /// The car's epoch as the last welcome said, if any.
    pub fn epoch(&self) -> Option<u32> {
        self.sync.map(|s| s.epoch)
    }

    /// Refused PDUs so far.
    pub const fn refusals(&self) -> RefusalStats {
        self.refused
    }

    /// Whether the message opened last carried a car counter above every one accepted before in
    /// its epoch (a welcome that is accepted always does). A message that is not the newest was
    /// overtaken on the way by one the car sent after it (reordered or delayed, by the bus or by
    /// anyone on it): what it says of the car's state is older than what the host already took
    /// from the newer one.
    pub const fn opened_newest(&self) -> bool {
        self.newest
    }

    /// A hello with `nonce` (a number never used before: random), telling the car the epoch and
    /// counter the host is at. Only a welcome repeating this nonce is accepted from now on.
    pub fn hello(&mut self, nonce: [u8; NONCE_LEN]) -> Message {
        self.nonce = Some(nonce);
        let (epoch, counter) = self
            .sync
            .map_or((0, 0), |s| (s.epoch, s.next_tx.unwrap_or(u32::MAX)));
        Message::Hello(Hello {
            nonce,
            epoch,
            counter,
        })
    }

    fn refuse(&mut self, r: Refusal) -> OpenError {
        self.refused.count(r);
        OpenError::Refused(r)
    }

    fn on_welcome(&mut self, w: &Welcome) -> Result<(), Refusal> {
        if self.nonce != Some(w.nonce) {
            return Err(Refusal::Stale);
        }
        match &mut self.sync {
            Some(s) if s.epoch == w.epoch => {
                s.rx.check(w.counter)?;
                // A welcome that newer messages of the car overtook on the way (delayed or
                // reordered, by the bus or by anyone) says what the car held before them: older
                // than what the host already took from them. The host is synchronised with this
                // epoch already (it accepted them), so the welcome brings nothing but an old
                // status, which would read as a car that lost what it was taught.
                if s.rx.highest().is_some_and(|h| w.counter < h) {
                    return Err(Refusal::Stale);
                }
                s.rx.accept(w.counter);
                let next = s.next_tx.unwrap_or(u32::MAX);
                if w.host_next > next {
                    s.next_tx = Some(w.host_next);
                }
            }
            _ => {
                let mut rx = ReplayWindow::new();
                rx.accept(w.counter);
                self.sync = Some(Sync {
                    epoch: w.epoch,
                    next_tx: Some(w.host_next),
                    rx,
                });
            }
        }
        Ok(())
    }
}

impl Endpoint for HostSecurity {
    fn seal<'b>(
        &mut self,
        msg: &Message,
        stream: Stream,
        buf: &'b mut [u8],
    ) -> Result<&'b [u8], SealError> {
        if let Message::Hello(_) = msg {
            return seal_pdu(msg, stream, &self.auth, Freshness::HELLO, buf)
                .map_err(SealError::Encode);
        }
        let s = self.sync.as_mut().ok_or(SealError::Unsynced)?;
        let counter = s.next_tx.ok_or(SealError::Exhausted)?;
        let fv = Freshness {
            epoch: s.epoch,
            counter,
        };
        let bytes = seal_pdu(msg, stream, &self.auth, fv, buf).map_err(SealError::Encode)?;
        s.next_tx = counter.checked_add(1);
        Ok(bytes)
    }

    /// Authenticates before it parses, but for a welcome (its MAC covers the freshness value it
    /// carries, so it is decoded first): of any other PDU whose MAC does not verify, nothing is
    /// decoded but the variant tag ([`SecuredPdu::kind`]).
    fn open(&mut self, stream: Stream, pdu: &[u8]) -> Result<Message, OpenError> {
        self.newest = false;
        let pdu = SecuredPdu::new_checked(pdu)?;
        if pdu.kind() == Some(MessageKind::Welcome)
            && let msg = pdu.message()?
            && let Message::Welcome(w) = &msg
        {
            let fv = Freshness {
                epoch: w.epoch,
                counter: w.counter,
            };
            let authentic = pdu.freshness_byte() == w.counter as u8
                && self.auth.verify(stream, pdu.body(), fv, pdu.tag());
            if !authentic {
                return Err(self.refuse(Refusal::Mac));
            }
            let w = *w;
            return match self.on_welcome(&w) {
                Ok(()) => {
                    // Above every counter accepted in its epoch, or the first of a new one.
                    self.newest = true;
                    Ok(msg)
                }
                Err(r) => Err(self.refuse(r)),
            };
        }
        let Some(s) = self.sync else {
            return Err(self.refuse(Refusal::Unsynced));
        };
        let counter = s.rx.resolve(pdu.freshness_byte());
        let fv = Freshness {
            epoch: s.epoch,
            counter,
        };
        if !self.auth.verify(stream, pdu.body(), fv, pdu.tag()) {
            return Err(self.refuse(Refusal::Mac));
        }
        if let Err(r) = s.rx.check(counter) {
            return Err(self.refuse(r));
        }
        let msg = pdu.message()?;
        self.newest = s.rx.highest().is_none_or(|h| counter > h);
        if let Some(s) = &mut self.sync {
            s.rx.accept(counter);
        }
        Ok(msg)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::message::{CarStatus, MAX_MESSAGE_SIZE};
    use crate::stream::Direction;
    use cmac::{Cmac, Mac};
    use proptest::prelude::*;
    use std::vec::Vec;

    /// RustCrypto's AES-CMAC of `m`: an implementation independent of [`Authenticator`]'s.
    fn oracle(key: &[u8; KEY_LEN], m: &[u8]) -> [u8; 16] {
        let mut c = <Cmac<Aes128Enc> as KeyInit>::new(&(*key).into());
        c.update(m);
        c.finalize().into_bytes().into()
    }

    fn hex(s: &str) -> Vec<u8> {
        (0..s.len())
            .step_by(2)
            .map(|i| u8::from_str_radix(&s[i..i + 2], 16).unwrap())
            .collect()
    }

    /// RFC 4493 (AES-CMAC) section 4, the four examples, through [`Authenticator`] and through
    /// the independent implementation the other tests compare it with.
    #[test]
    fn aes_cmac_matches_rfc_4493() {
        let key = Key::from_hex("2b7e151628aed2a6abf7158809cf4f3c").unwrap();
        let m = hex(
            "6bc1bee22e409f96e93d7e117393172aae2d8a571e03ac9c9eb76fac45af8e51\
             30c81c46a35ce411e5fbc1191a0a52eff69f2445df4f9b17ad2b417be66c3710",
        );
        let auth = Authenticator::new(&key);
        let mac = |len: usize| {
            let ours = auth.cmac([&m[..len], &[], &[]]);
            assert_eq!(ours, oracle(key.bytes(), &m[..len]), "{len} bytes");
            ours.to_vec()
        };
        assert_eq!(mac(0), hex("bb1d6929e95937287fa37d129b756746"));
        assert_eq!(mac(16), hex("070a16b46b4d4144f79bdd9dd04a287c"));
        assert_eq!(mac(40), hex("dfa66747de9ae63030ca32611497c827"));
        assert_eq!(mac(64), hex("51f0bebf7e3b9d92fc49741779363cfe"));
    }

    #[test]
    fn keys_read_and_write_as_hex() {
        let k = Key::from_hex("  000102030405060708090A0b0c0d0e0f\n").unwrap();
        assert_eq!(k.bytes(), &core::array::from_fn(|i| i as u8));
        assert_eq!(&k.to_hex(), b"000102030405060708090a0b0c0d0e0f");
        assert_eq!(Key::from_hex("0011"), Err(KeyError::Length(4)));
        assert_eq!(
            Key::from_hex("000102030405060708090a0b0c0d0e0g"),
            Err(KeyError::NotHex(31))
        );
        assert_eq!(Key::from_hex("é0").unwrap_err(), KeyError::Length(3));
        assert!(Key::INSECURE.is_insecure() && !k.is_insecure());
        assert_eq!(std::format!("{k:?}"), "Key(..)");
    }

    fn stream(kind: MessageKind, dir: Direction) -> Stream {
        Stream::for_kind(kind, dir).unwrap()
    }

    const KEY: Key = Key([0x42; KEY_LEN]);

    #[test]
    fn golden_secured_pdu() {
        // A heartbeat from the car in epoch 0x01020304, counter 0x105: version 3, variant 5,
        // the counter's low byte, the first four bytes of the CMAC over
        // 0x0103 ‖ 03 05 ‖ 01020304 00000105.
        let auth = Authenticator::new(&KEY);
        let s = stream(MessageKind::Heartbeat, Direction::CarToHost);
        let fv = Freshness {
            epoch: 0x0102_0304,
            counter: 0x105,
        };
        let mut buf = [0u8; 16];
        let pdu = seal_pdu(&Message::Heartbeat, s, &auth, fv, &mut buf).unwrap();
        let mut input = std::vec![0x01, 0x03, 4, 5];
        input.extend_from_slice(&[1, 2, 3, 4, 0, 0, 1, 5]);
        let full = oracle(KEY.bytes(), &input);
        assert_eq!(pdu, &[4, 5, 0x05, full[0], full[1], full[2], full[3]]);
        assert_eq!(
            pdu,
            &[4, 5, 0x05, 0xEB, 0x66, 0xB5, 0xD1],
            "the golden bytes"
        );
        let v = SecuredPdu::new_checked(pdu).unwrap();
        assert_eq!((v.payload(), v.freshness_byte()), (&[5u8][..], 5));
        assert!(auth.verify(s, v.body(), fv, v.tag()));
        // Another stream, epoch, counter or key: another MAC.
        let other = stream(MessageKind::Heartbeat, Direction::HostToCar);
        assert!(!auth.verify(other, v.body(), fv, v.tag()));
        let later = Freshness {
            counter: 0x205,
            ..fv
        };
        assert!(!auth.verify(s, v.body(), later, v.tag()));
        assert!(!Authenticator::new(&Key::INSECURE).verify(s, v.body(), fv, v.tag()));
    }

    #[test]
    fn the_window_accepts_each_counter_once_and_reordered_ones_within_its_reach() {
        let mut w = ReplayWindow::new();
        assert_eq!(w.resolve(7), 7);
        for c in [0, 1, 2, 5, 4, 3, 100, 99, 37] {
            assert_eq!(w.check(c), Ok(()), "{c}");
            w.accept(c);
            assert_eq!(w.check(c), Err(Refusal::Replayed), "{c} again");
        }
        assert_eq!(w.highest(), Some(100));
        assert_eq!(w.check(36), Err(Refusal::Stale), "64 below the highest");
        assert_eq!(w.check(38), Ok(()));
        // The low byte resolves to the counter nearest the highest.
        assert_eq!(w.resolve(101), 101);
        assert_eq!(w.resolve(99), 99);
        assert_eq!(w.resolve(227), 227);
        assert_eq!(w.resolve(228), 228, "no counter is below 0");
        let mut w = ReplayWindow::new();
        w.accept(1000);
        assert_eq!(w.resolve((1000u32 + 127) as u8), 1127);
        assert_eq!(w.resolve((1000u32 - 128) as u8), 872);
        // A jump past the window forgets it.
        w.accept(1200);
        assert_eq!(w.check(1000), Err(Refusal::Stale));
        // Advancing moves the floor forward only.
        w.advance_to(1300);
        assert_eq!((w.next(), w.check(1299)), (1300, Ok(())));
        assert_eq!(w.check(1200), Err(Refusal::Stale));
        w.advance_to(10);
        assert_eq!(w.next(), 1300);
    }

    /// `msg` sealed by `e` for stream `s`, as bytes.
    fn sealed(e: &mut impl Endpoint, msg: &Message, s: Stream) -> Vec<u8> {
        let mut buf = [0u8; MAX_MESSAGE_SIZE];
        e.seal(msg, s, &mut buf).unwrap().to_vec()
    }

    fn welcomed(key: &Key, car: &mut CarSecurity) -> HostSecurity {
        let mut host = HostSecurity::new(key);
        let hello = host.hello([9; NONCE_LEN]);
        let to_car = stream(MessageKind::Hello, Direction::HostToCar);
        let from_car = stream(MessageKind::Welcome, Direction::CarToHost);
        let mut buf = [0u8; MAX_MESSAGE_SIZE];
        let pdu = host.seal(&hello, to_car, &mut buf).unwrap().to_vec();
        let Ok(Message::Hello(h)) = car.open(to_car, &pdu) else {
            panic!("the car takes the hello")
        };
        car.on_hello(&h);
        let w = Message::Welcome(car.welcome(&h, CarStatus::default()));
        let pdu = car.seal(&w, from_car, &mut buf).unwrap().to_vec();
        assert_eq!(host.open(from_car, &pdu), Ok(w));
        host
    }

    #[test]
    fn a_welcome_synchronises_the_host_and_copies_are_refused() {
        let mut car = CarSecurity::new(&KEY, 77);
        let mut host = welcomed(&KEY, &mut car);
        assert_eq!(host.epoch(), Some(77));
        let to_car = stream(MessageKind::Reset, Direction::HostToCar);
        let reset = sealed(&mut host, &Message::Reset, to_car);
        assert_eq!(car.open(to_car, &reset), Ok(Message::Reset));
        // A replay of the same bytes is a copy.
        assert_eq!(
            car.open(to_car, &reset),
            Err(OpenError::Refused(Refusal::Replayed))
        );
        // A host with another key, or none (the insecure key), is refused.
        for wrong in [Key([7; KEY_LEN]), Key::INSECURE] {
            let mut other = HostSecurity::assume_fresh_car(&wrong, 77);
            let forged = sealed(&mut other, &Message::Reset, to_car);
            assert_eq!(
                car.open(to_car, &forged),
                Err(OpenError::Refused(Refusal::Mac))
            );
        }
        // Moved to another stream, it does not verify.
        let elsewhere = stream(MessageKind::Observation, Direction::HostToCar);
        let reset2 = sealed(&mut host, &Message::Reset, to_car);
        assert_eq!(
            car.open(elsewhere, &reset2),
            Err(OpenError::Refused(Refusal::Mac))
        );
        let r = car.refusals();
        assert_eq!((r.replayed, r.mac, r.total()), (1, 3, 4));
        // A message that never arrived, delivered late (by anyone): accepted once, not the
        // newest.
        let late = sealed(&mut host, &Message::Reset, to_car);
        let later = sealed(&mut host, &Message::Reset, to_car);
        assert_eq!(car.open(to_car, &later), Ok(Message::Reset));
        assert!(car.opened_newest());
        assert_eq!(car.open(to_car, &late), Ok(Message::Reset));
        assert!(!car.opened_newest());
        // A restarted car (new epoch) refuses what the host sends in the old one.
        let mut restarted = CarSecurity::new(&KEY, 78);
        let reset3 = sealed(&mut host, &Message::Reset, to_car);
        assert_eq!(
            restarted.open(to_car, &reset3),
            Err(OpenError::Refused(Refusal::Mac))
        );
        let mut host = welcomed(&KEY, &mut restarted);
        assert_eq!(host.epoch(), Some(78));
        let reset4 = sealed(&mut host, &Message::Reset, to_car);
        assert_eq!(restarted.open(to_car, &reset4), Ok(Message::Reset));
    }

    #[test]
    fn the_host_refuses_everything_but_the_welcome_to_its_own_hello() {
        let mut car = CarSecurity::new(&KEY, 5);
        let from_car = stream(MessageKind::Heartbeat, Direction::CarToHost);
        let mut buf = [0u8; MAX_MESSAGE_SIZE];
        let hb = sealed(&mut car, &Message::Heartbeat, from_car);
        let mut host = HostSecurity::new(&KEY);
        assert_eq!(
            host.open(from_car, &hb),
            Err(OpenError::Refused(Refusal::Unsynced))
        );
        // A welcome to a hello the host never sent (a replay, or the car's answer to another
        // host) is refused.
        let h = Hello {
            nonce: [1; NONCE_LEN],
            epoch: 0,
            counter: 0,
        };
        let w = Message::Welcome(car.welcome(&h, CarStatus::default()));
        let ws = stream(MessageKind::Welcome, Direction::CarToHost);
        let pdu = car.seal(&w, ws, &mut buf).unwrap().to_vec();
        host.hello([2; NONCE_LEN]);
        assert_eq!(host.open(ws, &pdu), Err(OpenError::Refused(Refusal::Stale)));
        assert_eq!(host.epoch(), None);
    }

    #[test]
    fn a_welcome_overtaken_by_newer_messages_of_the_car_is_refused() {
        let mut car = CarSecurity::new(&KEY, 9);
        let mut host = welcomed(&KEY, &mut car);
        let mut buf = [0u8; MAX_MESSAGE_SIZE];
        let from_car = stream(MessageKind::Heartbeat, Direction::CarToHost);
        // The host says hello again (same epoch); the car welcomes it, then answers on: its
        // status moves on (a feedback applied) and so do its counters.
        let hello = host.hello([4; NONCE_LEN]);
        let Message::Hello(h) = hello else { panic!() };
        let old = CarStatus {
            session: Some(1),
            generation: 17,
        };
        let w = Message::Welcome(car.welcome(&h, old));
        let ws = stream(MessageKind::Welcome, Direction::CarToHost);
        let late = car.seal(&w, ws, &mut buf).unwrap().to_vec();
        let newer = sealed(&mut car, &Message::Heartbeat, from_car);
        // The welcome is held back on the way; the newer message arrives first.
        assert_eq!(host.open(from_car, &newer), Ok(Message::Heartbeat));
        assert_eq!(
            host.open(ws, &late),
            Err(OpenError::Refused(Refusal::Stale))
        );
        assert_eq!(host.refusals().stale, 1);
        // Nothing else changed: the car's next message is accepted, the newest.
        let next = sealed(&mut car, &Message::Heartbeat, from_car);
        assert_eq!(host.open(from_car, &next), Ok(Message::Heartbeat));
        assert!(host.opened_newest());
        // Any other message overtaken on the way is accepted once, not as the newest.
        let overtaken = sealed(&mut car, &Message::Heartbeat, from_car);
        let overtaking = sealed(&mut car, &Message::Heartbeat, from_car);
        assert_eq!(host.open(from_car, &overtaking), Ok(Message::Heartbeat));
        assert!(host.opened_newest());
        assert_eq!(host.open(from_car, &overtaken), Ok(Message::Heartbeat));
        assert!(!host.opened_newest());
        assert_eq!(
            host.open(from_car, &overtaken),
            Err(OpenError::Refused(Refusal::Replayed))
        );
        assert!(!host.opened_newest());
        // In order, the same welcome is accepted.
        let mut car = CarSecurity::new(&KEY, 10);
        let mut host = welcomed(&KEY, &mut car);
        let Message::Hello(h) = host.hello([5; NONCE_LEN]) else {
            panic!()
        };
        let w = Message::Welcome(car.welcome(&h, old));
        let on_time = car.seal(&w, ws, &mut buf).unwrap().to_vec();
        let after = sealed(&mut car, &Message::Heartbeat, from_car);
        assert_eq!(host.open(ws, &on_time), Ok(w));
        assert!(host.opened_newest());
        assert_eq!(host.open(from_car, &after), Ok(Message::Heartbeat));
        assert!(host.opened_newest());
    }

    #[test]
    fn a_hello_moves_the_car_past_counters_it_never_saw() {
        let mut car = CarSecurity::new(&KEY, 3);
        let mut host = welcomed(&KEY, &mut car);
        let to_car = stream(MessageKind::Heartbeat, Direction::HostToCar);
        let mut buf = [0u8; MAX_MESSAGE_SIZE];
        // 300 heartbeats lost on the way: the car's window can no longer place the low byte.
        for _ in 0..300 {
            host.seal(&Message::Heartbeat, to_car, &mut buf).unwrap();
        }
        let hb = sealed(&mut host, &Message::Heartbeat, to_car);
        assert_eq!(car.open(to_car, &hb), Err(OpenError::Refused(Refusal::Mac)));
        // Hello again (same epoch): the car moves its window to the host's counter.
        let hello = host.hello([3; NONCE_LEN]);
        let hs = stream(MessageKind::Hello, Direction::HostToCar);
        let pdu = host.seal(&hello, hs, &mut buf).unwrap().to_vec();
        let Ok(Message::Hello(h)) = car.open(hs, &pdu) else {
            panic!()
        };
        assert_eq!(h.counter, 301);
        car.on_hello(&h);
        assert_eq!(car.host_next(), 301);
        let hb = sealed(&mut host, &Message::Heartbeat, to_car);
        assert_eq!(car.open(to_car, &hb), Ok(Message::Heartbeat));
        // The replayed hello changes nothing, and old counters stay refused.
        let Ok(Message::Hello(h)) = car.open(hs, &pdu) else {
            panic!()
        };
        car.on_hello(&h);
        assert_eq!(car.host_next(), 302);
    }

    #[test]
    fn an_unkeyed_car_refuses_and_sends_nothing() {
        let mut car = CarSecurity::unkeyed();
        let s = stream(MessageKind::Heartbeat, Direction::CarToHost);
        let mut buf = [0u8; 16];
        assert_eq!(
            car.seal(&Message::Heartbeat, s, &mut buf),
            Err(SealError::Unkeyed)
        );
        let mut host = HostSecurity::assume_fresh_car(&KEY, 1);
        let to_car = stream(MessageKind::Heartbeat, Direction::HostToCar);
        let pdu = sealed(&mut host, &Message::Heartbeat, to_car);
        assert_eq!(
            car.open(to_car, &pdu),
            Err(OpenError::Refused(Refusal::Unkeyed))
        );
    }

    /// A PDU of the right length and version whose payload does not decode and whose MAC does
    /// not verify: refused as a forgery and counted, on either side, whatever variant tag it
    /// starts with (its payload is never decoded). Before 2026-12-03 both sides decoded first,
    /// and called such bytes a decode error.
    #[test]
    fn a_strangers_bytes_are_refused_before_they_are_decoded() {
        let mut car = CarSecurity::new(&KEY, 9);
        let mut host = HostSecurity::assume_fresh_car(&KEY, 9);
        for tag in [MessageKind::Hello as u8, MessageKind::Feedback as u8, 0x7f] {
            // The tag, then bytes no message decodes from (a varint that never ends).
            let pdu = [
                PROTOCOL_VERSION,
                tag,
                0xff,
                0xff,
                0xff,
                0xff,
                0xff,
                0,
                1,
                2,
                3,
                4,
            ];
            let bad = SecuredPdu::new_checked(&pdu).unwrap();
            assert!(bad.message().is_err(), "tag {tag}");
            let to_car = stream(MessageKind::Feedback, Direction::HostToCar);
            assert_eq!(
                car.open(to_car, &pdu),
                Err(OpenError::Refused(Refusal::Mac))
            );
            let to_host = stream(MessageKind::Ack, Direction::CarToHost);
            assert_eq!(
                host.open(to_host, &pdu),
                Err(OpenError::Refused(Refusal::Mac))
            );
        }
        assert_eq!(car.refusals().mac, 3);
        assert_eq!(host.refusals().mac, 3);
    }

    /// An authentic, fresh PDU whose payload does not decode (a heartbeat with a byte too many,
    /// MAC'd with the key): a decode error, and its counter is not taken.
    #[test]
    fn an_authentic_pdu_that_does_not_decode_takes_no_counter() {
        let mut car = CarSecurity::new(&KEY, 9);
        let s = stream(MessageKind::Heartbeat, Direction::HostToCar);
        let fv = Freshness {
            epoch: 9,
            counter: 0,
        };
        let mut pdu = vec![PROTOCOL_VERSION, MessageKind::Heartbeat as u8, 0xaa];
        let tag = Authenticator::new(&KEY).tag(s, &pdu, fv);
        pdu.push(0);
        pdu.extend_from_slice(&tag);
        assert!(matches!(car.open(s, &pdu), Err(OpenError::Decode(_))));
        assert_eq!(car.refusals().total(), 0);
        assert_eq!(car.host_next(), 0);
        let mut host = HostSecurity::assume_fresh_car(&KEY, 9);
        let good = sealed(&mut host, &Message::Heartbeat, s);
        assert_eq!(car.open(s, &good), Ok(Message::Heartbeat));
        assert_eq!(car.host_next(), 1);
    }

    proptest! {
        /// The MAC equals the independent implementation's over `CAN id ‖ body ‖ freshness`,
        /// for any key and any body length (whole blocks, padded ones, several blocks), and
        /// `verify` accepts exactly the truncated tag.
        #[test]
        fn the_mac_is_aes_cmac_over_id_body_and_freshness(
            key in any::<[u8; KEY_LEN]>(),
            body in proptest::collection::vec(any::<u8>(), 0..100),
            epoch in any::<u32>(),
            counter in any::<u32>(),
            flip in 0..MAC_LEN * 8,
        ) {
            let auth = Authenticator::new(&Key::new(key));
            let s = stream(MessageKind::Observation, Direction::HostToCar);
            let fv = Freshness { epoch, counter };
            let mut input = s.raw_id().to_be_bytes().to_vec();
            input.extend_from_slice(&body);
            input.extend_from_slice(&fv.to_be_bytes());
            let full = auth.full_tag(s, &body, fv);
            prop_assert_eq!(full, oracle(&key, &input));
            let tag = auth.tag(s, &body, fv);
            prop_assert_eq!(&tag[..], &full[..MAC_LEN]);
            prop_assert!(auth.verify(s, &body, fv, &tag));
            let mut wrong = tag;
            wrong[flip / 8] ^= 1 << (flip % 8);
            prop_assert!(!auth.verify(s, &body, fv, &wrong));
            prop_assert!(!auth.verify(s, &body, fv, &tag[..MAC_LEN - 1]));
        }

        /// Any bytes: a message, or a refusal / decode error, never a panic; and never accepted
        /// without the key.
        #[test]
        fn forged_bytes_are_never_accepted(bytes in proptest::collection::vec(any::<u8>(), 0..200)) {
            let mut car = CarSecurity::new(&KEY, 9);
            let s = stream(MessageKind::Feedback, Direction::HostToCar);
            prop_assert!(car.open(s, &bytes).is_err());
        }

        /// Delivered out of order, duplicated and with losses (no more than 127 in a row), every
        /// message is accepted exactly once.
        #[test]
        fn reordered_and_duplicated_pdus_are_accepted_once(
            order in proptest::collection::vec((0u32..8, any::<bool>(), 0u8..10), 1..400)
        ) {
            let mut car = CarSecurity::new(&KEY, 9);
            let mut host = HostSecurity::assume_fresh_car(&KEY, 9);
            let s = stream(MessageKind::Heartbeat, Direction::HostToCar);
            let mut sent = Vec::new();
            for _ in 0..order.len() {
                let mut buf = [0u8; 16];
                sent.push(host.seal(&Message::Heartbeat, s, &mut buf).unwrap().to_vec());
            }
            // Reverse some blocks of eight (reordered by up to 7), duplicate some, lose some.
            let mut queue: Vec<usize> = (0..sent.len()).collect();
            for (b, block) in queue.chunks_mut(8).enumerate() {
                if order[b * 8].0 % 2 == 1 {
                    block.reverse();
                }
            }
            let mut accepted = std::collections::HashSet::new();
            for (k, &i) in queue.iter().enumerate() {
                let (_, dup, lose) = order[k];
                if lose == 0 {
                    continue;
                }
                for _ in 0..if dup { 2 } else { 1 } {
                    if car.open(s, &sent[i]).is_ok() {
                        prop_assert!(accepted.insert(i), "{} accepted twice", i);
                    }
                }
            }
            let lost = order.iter().filter(|o| o.2 == 0).count();
            prop_assert_eq!(accepted.len(), sent.len() - lost);
        }
    }
}
