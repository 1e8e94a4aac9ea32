//! What a link is, whatever moves its bytes (sans-IO): the router's link
//! tasks, the blocking `conn::Connection` and the `embedded` adapters all
//! drive these parts, and differ only in how bytes come and go.
//!
//! - [`Inbox`]: the receive side. Bytes come in (with the address they
//!   came from, and whether they were one whole datagram, whose end ends
//!   every frame in it); frames the parser accepts come out (checksums,
//!   the key's verifier and the unsigned policy).
//! - [`LinkCore`]: an inbox and a [`Framer`] (sequence numbers, signer).
//!   The signer adopts the timestamps the verifier accepted
//!   ([`Framer::adopt_from`]) after each frame and before each send.
//! - With `std`: [`Peers`], whom a blocking link that several remote ends
//!   share sends to (a [`ReplyTo`] rule over a [`PeerSet`](crate::peers::PeerSet));
//!   [`SigningFile`], when the link's signing state is saved.

// Each front end uses the parts it needs; the router (feature `tokio`),
// all but `Peers` (whom its links answer is its policy's).
#![cfg_attr(not(feature = "tokio"), allow(dead_code))]

use crate::framer::Framer;
use crate::message::MessageSet;
use crate::parser::{Parser, Received};
use crate::received::ReceivedBuf;
use core::net::SocketAddr;

#[cfg(feature = "std")]
pub(crate) use self::std_parts::Peers;
#[cfg(feature = "tokio")]
pub(crate) use self::std_parts::SigningFile;

/// The receive side of a link: the parser, and the bytes received but not
/// parsed yet (`buf[start..end]`).
pub(crate) struct Inbox<D: MessageSet, B, const STREAMS: usize = 16> {
    pub(crate) parser: Parser<D, STREAMS>,
    buf: B,
    start: usize,
    end: usize,
    /// The bytes held are one whole datagram.
    datagram: bool,
    /// The parser has not been told yet that the datagram ended.
    datagram_open: bool,
    /// Where the bytes held came from.
    pub(crate) source: Option<SocketAddr>,
    /// Bytes parsed by one [`take`](Self::take) at most.
    chunk: usize,
}

impl<D: MessageSet, B: AsRef<[u8]> + AsMut<[u8]>, const S: usize> Inbox<D, B, S> {
    /// An inbox reading into `buf`.
    pub(crate) fn new(parser: Parser<D, S>, buf: B) -> Self {
        Inbox {
            parser,
            buf,
            start: 0,
            end: 0,
            datagram: false,
            datagram_open: false,
            source: None,
            chunk: usize::MAX,
        }
    }

    /// Parses at most `chunk` bytes per [`take`](Self::take): a caller
    /// that must not hold its thread for long (an async task) lets others
    /// run in between, while [`held`](Self::held) says bytes remain.
    pub(crate) fn set_chunk(&mut self, chunk: usize) {
        self.chunk = chunk.max(1);
    }

    /// Where to receive into: the whole buffer (received into only once
    /// parsed to the end; the parser keeps a partial frame).
    pub(crate) fn space(&mut self) -> &mut [u8] {
        self.buf.as_mut()
    }

    /// `n` bytes were received into [`space`](Self::space) from `source`;
    /// `datagram`: they are one whole datagram (no frame goes on past
    /// them). A count beyond the buffer is believed up to its length.
    pub(crate) fn received(&mut self, n: usize, source: Option<SocketAddr>, datagram: bool) {
        self.start = 0;
        self.end = n.min(self.buf.as_ref().len());
        self.datagram = datagram;
        self.datagram_open = datagram;
        self.source = source;
    }

    /// Bytes held and not parsed yet.
    pub(crate) fn held(&self) -> usize {
        self.end - self.start
    }

    /// The next frame in the bytes held (at a datagram's end, those its end
    /// decides), handed to `f`; `Err(f)` when they hold none (and then,
    /// unless [`held`](Self::held), the buffer is free to receive into).
    ///
    /// A closure rather than a returned frame keeps the borrow checker
    /// content in the callers' receive loops.
    pub(crate) fn take<T, F: FnOnce(Received<'_, D>) -> T>(&mut self, f: F) -> Result<T, F> {
        // Even with no bytes held: the parser may hold frames of its own
        // (the good ones found again after a candidate it gave up).
        let stop = self.end.min(self.start.saturating_add(self.chunk));
        let last = stop == self.end;
        let mut input = self.buf.as_ref().get(self.start..stop).unwrap_or(&[]);
        let got = if self.datagram && last && !input.is_empty() {
            self.parser.next_in_datagram(&mut input)
        } else {
            self.parser.next(&mut input)
        };
        // The parser consumes all its input before it says None.
        self.start = match got {
            Some(_) => stop - input.len(),
            None => stop,
        };
        match got {
            Some(r) => return Ok(f(r)),
            None if !last => return Err(f),
            None => {}
        }
        if self.datagram_open {
            match self.parser.end_of_datagram() {
                Some(r) => return Ok(f(r)),
                None => self.datagram_open = false,
            }
        }
        Err(f)
    }

    /// [`take`](Self::take), copied out.
    pub(crate) fn next(&mut self) -> Option<ReceivedBuf<D>> {
        self.take(|r| ReceivedBuf::from(&r)).ok()
    }

    /// At the end of the stream: the bytes held, decided as if nothing
    /// follows (call until `None`).
    pub(crate) fn take_at_eof<T>(&mut self, f: impl FnOnce(Received<'_, D>) -> T) -> Option<T> {
        match self.take(f) {
            Ok(t) => Some(t),
            Err(f) => self.parser.flush().map(f),
        }
    }

    /// Whether `frame` vouches for its sender (makes it a peer under
    /// [`ReplyTo::Accepted`]): any frame the parser accepted, and on a link
    /// with a key only an authenticated one (an unsigned frame, even
    /// accepted, is anyone's).
    pub(crate) fn vouches(&self, frame: &ReceivedBuf<D>) -> bool {
        frame.is_authenticated() || self.parser.verifier().is_none()
    }
}

/// One link: its [`Inbox`] and its [`Framer`], whose signer follows what
/// the inbox's verifier accepted.
pub(crate) struct LinkCore<D: MessageSet, B, const STREAMS: usize = 16> {
    pub(crate) inbox: Inbox<D, B, STREAMS>,
    pub(crate) framer: Framer,
}

impl<D: MessageSet, B: AsRef<[u8]> + AsMut<[u8]>, const S: usize> LinkCore<D, B, S> {
    /// The signer adopts what the verifier accepted: after receiving,
    /// and before framing (a verifier with a clock moves on meanwhile).
    pub(crate) fn adopt(&mut self) {
        self.framer.adopt_from(self.inbox.parser.verifier());
    }
}

#[cfg(feature = "std")]
/// Whom a blocking link that several remote ends share sends to
/// (`conn::UdpIn`, `conn::UdpBcast`; the router's listening links send to
/// whom its policy names, as `router::Forward` does by
/// the `Accepted` rule).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub enum ReplyTo {
    /// The senders of frames the parser accepted (authenticated ones only,
    /// when the link has a key), up to [`MAX_PEERS`](crate::peers::MAX_PEERS) of them, by the rule
    /// of [`crate::peers`] (the default). A datagram without such a frame
    /// moves nothing; a stranger with valid frames gets a free slot, or
    /// the slot of a peer silent for [`SILENCE`](crate::peers::SILENCE),
    /// never a speaking station's.
    #[default]
    Accepted,
    /// This address only, whoever else sends.
    Fixed(SocketAddr),
    /// Only the addresses the owner gives (`UdpIn::set_peers`; nobody
    /// until then): the application decides its peers by a policy of its
    /// own.
    Owner,
}

#[cfg(feature = "std")]
mod std_parts {
    use super::ReplyTo;
    use crate::parser::{Parser, Unsigned};
    use crate::peers::{PeerSet, MAX_PEERS};
    use crate::signing::state::{SigningState, StateFile};
    use crate::signing::Verifier;
    use crate::Framer;
    use core::net::SocketAddr;
    use std::io;
    use std::path::Path;
    use std::sync::{Arc, Mutex, MutexGuard, PoisonError};
    use std::time::Instant;

    /// Whom a link that several remote ends share (`udpin`, `udpbcast`,
    /// `tcpin`) sends to: its [`ReplyTo`] rule and its peers, by the rule
    /// of [`crate::peers`]. A clone (a split-off send half's) shares the
    /// peers.
    #[derive(Debug, Clone)]
    pub(crate) struct Peers {
        pub(crate) rule: ReplyTo,
        set: Arc<Mutex<PeerSet>>,
        /// The origin of the set's times.
        epoch: Instant,
    }

    impl Peers {
        pub(crate) fn new(rule: ReplyTo) -> Peers {
            Peers {
                rule,
                set: Arc::default(),
                epoch: Instant::now(),
            }
        }

        /// The set (a poisoned lock only means another thread panicked
        /// mid-copy of plain data: what is there is whole).
        fn set(&self) -> MutexGuard<'_, PeerSet> {
            self.set.lock().unwrap_or_else(PoisonError::into_inner)
        }

        /// A new rule, which starts with no peers.
        pub(crate) fn set_rule(&mut self, rule: ReplyTo) {
            if rule != self.rule {
                self.set().clear();
            }
            self.rule = rule;
        }

        /// `from` sent a frame the link accepted (one that vouches for it:
        /// [`Inbox::vouches`](super::Inbox::vouches)).
        pub(crate) fn heard(&mut self, from: Option<SocketAddr>) {
            if let (ReplyTo::Accepted, Some(from)) = (self.rule, from) {
                let now = self.epoch.elapsed();
                self.set().heard(from, now);
            }
        }

        /// The owner's peers.
        pub(crate) fn given(&mut self, addrs: &[SocketAddr]) {
            let now = self.epoch.elapsed();
            self.set().set(addrs, now);
        }

        /// Where frames go now: the fixed address, or the peer heard (or
        /// given) most recently.
        pub(crate) fn latest(&self) -> Option<SocketAddr> {
            match self.rule {
                ReplyTo::Fixed(addr) => Some(addr),
                _ => self.set().latest(),
            }
        }

        /// Every address a frame goes to: the fixed address, or the peers,
        /// or `fallback` (`udpbcast`'s broadcast address) while there is
        /// none. A copy: no lock is held while sending.
        pub(crate) fn targets(
            &self,
            fallback: Option<SocketAddr>,
        ) -> impl Iterator<Item = SocketAddr> {
            let mut all = [None; MAX_PEERS + 1];
            match self.rule {
                ReplyTo::Fixed(addr) => all[0] = Some(addr),
                _ => {
                    let set = self.set();
                    let fallback = fallback.filter(|_| set.is_empty());
                    for (slot, addr) in all.iter_mut().zip(set.iter().chain(fallback)) {
                        *slot = Some(addr);
                    }
                }
            }
            all.into_iter().flatten()
        }
    }

    /// A link's signing: the key, what its parser and framer start from,
    /// and the file its state is kept in.
    #[derive(Debug)]
    pub(crate) struct SigningFile {
        key: Option<[u8; 32]>,
        unsigned: Unsigned,
        file: Option<StateFile>,
        start: SigningState,
    }

    impl Default for SigningFile {
        /// No key, no file.
        fn default() -> Self {
            SigningFile {
                key: None,
                unsigned: Unsigned::Accept,
                file: None,
                start: SigningState::default(),
            }
        }
    }

    impl SigningFile {
        /// The signing of a link with `key` (none: unsigned), its state
        /// kept in `path`.
        pub(crate) fn open(
            key: Option<[u8; 32]>,
            unsigned: Unsigned,
            path: Option<&Path>,
        ) -> io::Result<SigningFile> {
            let file = match (path, key) {
                (Some(path), Some(_)) => Some(
                    StateFile::open(path)
                        .map_err(|e| {
                            io::Error::other(std::format!(
                                "signing state {}: {e}; remove the file to start from the clock",
                                path.display()
                            ))
                        })?
                        .0,
                ),
                (Some(_), None) => {
                    return Err(io::Error::new(
                        io::ErrorKind::InvalidInput,
                        "a signing state file needs a signing key",
                    ))
                }
                (None, _) => None,
            };
            let start = file.as_ref().map(|f| f.state().clone()).unwrap_or_default();
            Ok(SigningFile {
                key,
                unsigned,
                file,
                start,
            })
        }

        /// The key the link signs and verifies with.
        pub(crate) fn key(&self) -> Option<[u8; 32]> {
            self.key
        }

        /// A parser with the key's verifier, from the state saved.
        pub(crate) fn parser<D: crate::MessageSet>(&self) -> Parser<D> {
            match self.key {
                Some(key) => Parser::with_signing(self.start.verifier(key), self.unsigned),
                None => Parser::new(),
            }
        }

        /// The key's verifier as the state saved leaves it (`None`
        /// without a key).
        pub(crate) fn verifier(&self) -> Option<([u8; 32], Verifier)> {
            self.key.map(|key| (key, self.start.verifier(key)))
        }

        /// A framer with the key's signer, from the state saved.
        pub(crate) fn framer(&self) -> Framer {
            let mut framer = Framer::new();
            framer.set_signer(self.signer());
            framer
        }

        /// The key's signer, from the state saved.
        pub(crate) fn signer(&self) -> Option<crate::signing::Signer> {
            self.key.map(|key| self.start.signer(key, 0))
        }

        /// Signs and verifies with `key` from now on, from the clock (a
        /// new key has no timestamps of its own yet); the state file, if
        /// any, keeps the new key's.
        pub(crate) fn set_key(&mut self, key: Option<[u8; 32]>) {
            self.key = key;
            self.start = SigningState::default();
        }

        /// Parsers made from now on go on from here (a transport failed
        /// and is opened again).
        /// Whether the state is kept in a file.
        pub(crate) fn keeps_state(&self) -> bool {
            self.file.is_some()
        }

        pub(crate) fn go_on_from(&mut self, framer: &Framer, verifier: Option<&Verifier>) {
            self.start = SigningState::capture(framer.signer(), verifier);
        }

        /// Saves if due, or now as at exit (`last`: [`StateFile::save_final`],
        /// the signer's exact bound; its next signature makes a checkpoint
        /// due); false when the save failed. A failure leaves the last
        /// saved state in place and is retried a save interval later; the
        /// link goes on.
        pub(crate) fn save(
            &mut self,
            framer: &Framer,
            verifier: Option<&Verifier>,
            last: bool,
        ) -> bool {
            let signer = framer.signer();
            match &mut self.file {
                Some(file) if last => file.save_final(signer, verifier).is_ok(),
                Some(file) if file.due(signer) => file.save(signer, verifier).is_ok(),
                _ => true,
            }
        }
    }
}

#[cfg(test)]
#[cfg(feature = "std")]
mod tests {
    use super::*;
    use crate::conn::test_dialect::{Ping, TestDialect};
    use crate::signing::{Signer, Verifier};
    use crate::Unsigned;
    use std::vec::Vec;

    /// A MAVLink 2 header of Ping claiming a 200-byte payload.
    const FALSE_HEADER: [u8; 10] = [0xFD, 200, 0, 0, 0, 1, 1, 1, 0, 0];

    fn frames(values: &[u32]) -> Vec<u8> {
        let mut framer = Framer::new();
        let all = values
            .iter()
            .map(|&value| framer.frame(1, 1, &Ping { value }).unwrap().to_vec());
        all.collect::<Vec<_>>().concat()
    }

    /// Every frame the inbox holds, taken `chunk` bytes at a time as the
    /// router takes them (going on while bytes are held).
    fn take_all(bytes: &[u8], datagram: bool, chunk: usize) -> (Vec<u32>, usize) {
        let mut inbox = Inbox::<TestDialect, _>::new(Parser::new(), [0u8; 512]);
        inbox.set_chunk(chunk);
        inbox.space()[..bytes.len()].copy_from_slice(bytes);
        inbox.received(bytes.len(), None, datagram);
        let mut got = Vec::new();
        loop {
            match inbox.next() {
                Some(f) => got.push(f.message().unwrap().value),
                None if inbox.held() > 0 => {}
                None => break,
            }
        }
        (got, inbox.parser.pending())
    }

    /// A datagram's end decides a candidate it cuts (the false header is
    /// given up at once), however the bytes are chunked; on a stream the
    /// same bytes wait for the length the header claims.
    #[test]
    fn a_datagram_ends_its_frames_whatever_the_chunks() {
        let bytes = [&frames(&[1, 2, 3])[..], &FALSE_HEADER[..]].concat();
        for chunk in [1, 7, 64, usize::MAX] {
            assert_eq!(
                take_all(&bytes, true, chunk),
                (std::vec![1, 2, 3], 0),
                "{chunk}"
            );
            let (got, pending) = take_all(&bytes, false, chunk);
            assert_eq!((got, pending > 0), (std::vec![1, 2, 3], true), "{chunk}");
        }
    }

    /// The core's signer adopts the timestamp of a frame its verifier
    /// accepted: its next frame is signed no earlier.
    #[test]
    fn the_signer_follows_what_the_verifier_accepted() {
        let key = [9; 32];
        let mut peer = Framer::new();
        peer.set_clock(None);
        peer.set_signer(Some(Signer::new(key, 1, 5_000_000)));
        let bytes = peer.frame(2, 1, &Ping { value: 1 }).unwrap().to_vec();
        let verifier = Verifier::<16>::with_timestamp(key, 0);
        let parser = Parser::<TestDialect>::with_signing(verifier, Unsigned::Refuse);
        let mut own = Framer::new();
        own.set_clock(None);
        own.set_signer(Some(Signer::new(key, 0, 10)));
        let mut core = LinkCore {
            inbox: Inbox::new(parser, [0u8; 64]),
            framer: own,
        };
        core.inbox.space()[..bytes.len()].copy_from_slice(&bytes);
        core.inbox.received(bytes.len(), None, false);
        assert!(core.inbox.next().unwrap().is_authenticated());
        core.adopt();
        assert!(core.framer.signer().unwrap().timestamp() >= 5_000_000);
    }

    /// Whom a shared link sends to, by its rule: the fixed address only;
    /// the senders of accepted frames, else the fallback; the owner's, not
    /// a sender's. A clone (a split-off send half) sees the same peers.
    #[test]
    fn peers_follow_the_rule_and_are_shared_with_a_clone() {
        let (a, b, bcast): (SocketAddr, SocketAddr, SocketAddr) = (
            "10.0.0.1:1000".parse().unwrap(),
            "10.0.0.2:2000".parse().unwrap(),
            "10.0.0.255:14550".parse().unwrap(),
        );
        let targets = |p: &Peers, f| p.targets(f).collect::<Vec<_>>();
        let mut fixed = Peers::new(ReplyTo::Fixed(a));
        fixed.heard(Some(b));
        assert_eq!(targets(&fixed, Some(bcast)), [a]);
        let mut accepted = Peers::new(ReplyTo::Accepted);
        let half = accepted.clone();
        assert_eq!(targets(&half, Some(bcast)), [bcast]);
        accepted.heard(Some(b));
        assert_eq!(
            (targets(&half, Some(bcast)), half.latest()),
            (std::vec![b], Some(b))
        );
        let mut owner = Peers::new(ReplyTo::Owner);
        owner.heard(Some(b));
        assert!(targets(&owner, None).is_empty());
        owner.given(&[a]);
        assert_eq!(targets(&owner, None), [a]);
    }
}
