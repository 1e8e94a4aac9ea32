//! Signing across restarts, clock skews and stream floods: a fresh
//! verifier rejects old captures, the stream table evicts without a replay
//! hole or a lock-out, signers adopt the timestamps their link verified (so
//! a clock skew between two key holders does not stop their link), and the
//! state file carries the signer's bound and the verifier's timestamps over
//! a restart without moving the signer ahead.
#![cfg(feature = "std")]

use mavframe::conn::{AnyTransport, Connection, ReplyTo};
use mavframe::frame::{finish, Frame, Header, Version, MAX_FRAME_LEN};
use mavframe::message::{BufferTooSmall, MessageData, MessageMeta, MessageSet};
use mavframe::parser::{Parser, Stats, Unsigned};
use mavframe::signing::state::{Loaded, SigningState, StateError, StateFile, SIGNER_MARGIN};
use mavframe::signing::{timestamp_now, SignatureError, Signer, Verifier, NEW_STREAM_WINDOW};
use mavframe::Framer;
use std::path::PathBuf;
use std::sync::atomic::{AtomicU64, Ordering};
use std::time::Duration;

const KEY: [u8; 32] = *b"mavframe-signing-state-test-key!";

/// 10 µs units.
const SECOND: u64 = 100_000;
const HOUR: u64 = 3600 * SECOND;

const META: MessageMeta = MessageMeta::new(15001, "TEST_NOTICE", 77, 12, 12, &[]);

/// One signed frame from (`sysid`, `compid`) by `signer`.
fn signed(signer: &mut Signer, sysid: u8, compid: u8, seq: u8) -> Vec<u8> {
    let mut buf = [0u8; MAX_FRAME_LEN];
    buf[10..22].copy_from_slice(&[seq, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11]);
    let header = Header { seq, sysid, compid };
    let n = finish(Version::V2, header, &META, 12, Some(signer), &mut buf).unwrap();
    buf[..n].to_vec()
}

fn verify<const N: usize>(v: &mut Verifier<N>, bytes: &[u8]) -> Result<(), SignatureError> {
    v.verify(&Frame::new_checked(bytes).unwrap())
}

/// A fresh path under cargo's temporary directory for tests.
fn temp_path(name: &str) -> PathBuf {
    let dir = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join("signing_state");
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join(format!("{name}.{}", std::process::id()));
    let _ = std::fs::remove_file(&path);
    path
}

/// 50 captured notices, replayed into a freshly started
/// verifier. One started from the clock rejects them all (older than a
/// minute as a new stream); `Verifier::new` (the old live code) accepted
/// them, which is why it is documented as for recordings only.
#[test]
fn a_clock_started_verifier_rejects_old_captures() {
    let mut fc = Signer::new(KEY, 0, timestamp_now() - 10 * 60 * SECOND);
    let captured: Vec<Vec<u8>> = (0..50).map(|i| signed(&mut fc, 1, 1, i)).collect();

    let mut fresh: Verifier = Verifier::starting_now(KEY);
    for f in &captured {
        assert_eq!(verify(&mut fresh, f), Err(SignatureError::TooOld));
    }
    // The live FC, signing at the clock, is accepted.
    let mut live = Signer::new(KEY, 0, timestamp_now());
    assert_eq!(verify(&mut fresh, &signed(&mut live, 1, 1, 0)), Ok(()));

    let mut zero: Verifier = Verifier::new(KEY);
    assert_eq!(verify(&mut zero, &captured[0]), Ok(()));
}

static IDLE_CLOCK: AtomicU64 = AtomicU64::new(0);
fn idle_clock() -> u64 {
    IDLE_CLOCK.load(Ordering::Relaxed)
}

/// With a clock, the notion of now keeps up on an idle link: a capture two
/// minutes old of a stream the verifier never saw is rejected, though no
/// frame arrived in between. `with_timestamp` (no clock) stays at its start.
#[test]
fn a_verifier_with_a_clock_keeps_up_on_an_idle_link() {
    let t0 = 400_000_000 * SECOND;
    IDLE_CLOCK.store(t0, Ordering::Relaxed);
    let mut with_clock: Verifier = Verifier::with_clock(KEY, idle_clock);
    let mut without: Verifier = Verifier::with_timestamp(KEY, t0);
    let mut other = Signer::new(KEY, 0, t0 + 30 * SECOND);
    let capture = signed(&mut other, 5, 1, 0);
    IDLE_CLOCK.store(t0 + 150 * SECOND, Ordering::Relaxed);
    assert_eq!(
        verify(&mut with_clock, &capture),
        Err(SignatureError::TooOld)
    );
    assert_eq!(verify(&mut without, &capture), Ok(()));
    // Within the minute: accepted.
    let mut fresh = Signer::new(KEY, 0, t0 + 100 * SECOND);
    assert_eq!(
        verify(&mut with_clock, &signed(&mut fresh, 6, 1, 0)),
        Ok(())
    );
    assert_eq!(with_clock.newest_timestamp(), t0 + 150 * SECOND);
}

/// 16 other signers of the key take every slot, then the
/// legitimate companion (1, 191) arrives. It is accepted (the least recently
/// accepted stream is evicted), and keeps being accepted while 16 new
/// streams arrive between each of its frames (it is evicted each time and
/// comes back above its bucket's floor).
#[test]
fn n_plus_one_signers_do_not_lock_the_legitimate_stream_out() {
    let t0 = timestamp_now();
    let mut v: Verifier = Verifier::with_timestamp(KEY, t0);
    let mut t = t0;
    let mut others = 0u8;
    let mut other_frame = |v: &mut Verifier, t: u64| {
        others = others.wrapping_add(1);
        let mut s = Signer::new(KEY, 0, t);
        verify(v, &signed(&mut s, 100 + others % 100, others, 0))
    };
    for _ in 0..16 {
        t += 1_000;
        assert_eq!(other_frame(&mut v, t), Ok(()));
    }
    let mut cc = Signer::new(KEY, 0, t);
    for seq in 0..20 {
        cc.advance_to(t + 1_000);
        assert_eq!(
            verify(&mut v, &signed(&mut cc, 1, 191, seq)),
            Ok(()),
            "frame {seq}"
        );
        t = cc.timestamp();
        for _ in 0..16 {
            t += 1_000;
            assert_eq!(other_frame(&mut v, t), Ok(()));
        }
    }
}

/// A stream evicted by 16 others: its frames that were accepted cannot be
/// replayed as a "new" stream (they are not above the floor its eviction
/// left), and its next fresh frame is accepted.
#[test]
fn an_evicted_streams_old_frames_cannot_be_replayed() {
    let t0 = timestamp_now();
    let mut v: Verifier = Verifier::with_timestamp(KEY, t0);
    let mut fc = Signer::new(KEY, 0, t0);
    let sent: Vec<Vec<u8>> = (0..5).map(|i| signed(&mut fc, 1, 1, i)).collect();
    for f in &sent {
        assert_eq!(verify(&mut v, f), Ok(()));
    }
    for i in 0..16u8 {
        let mut s = Signer::new(KEY, 0, fc.timestamp() + 10 + u64::from(i));
        assert_eq!(verify(&mut v, &signed(&mut s, 50 + i, 1, 0)), Ok(()));
    }
    assert!(v.streams().all(|s| s.sysid != 1), "the FC was evicted");
    for f in &sent {
        assert_eq!(verify(&mut v, f), Err(SignatureError::BelowFloor));
    }
    assert_eq!(verify(&mut v, &signed(&mut fc, 1, 1, 5)), Ok(()));
    for f in &sent {
        assert_eq!(verify(&mut v, f), Err(SignatureError::Replay));
    }
}

/// A signer restarts with its clock 600 s behind. Without
/// its state it is rejected as a replay by a verifier that saw its earlier
/// frames; with its state file it starts after everything it sent and is
/// accepted at once.
#[test]
fn a_signer_restarted_with_its_clock_back_is_accepted_with_its_state() {
    let path = temp_path("signer_back");
    let t0 = timestamp_now();
    let mut v: Verifier = Verifier::with_timestamp(KEY, t0);
    let (mut file, loaded) = StateFile::open(&path).unwrap();
    assert_eq!(loaded, Loaded::Fresh);
    let mut fc = file.state().signer(KEY, 0);
    for seq in 0..100 {
        assert_eq!(verify(&mut v, &signed(&mut fc, 1, 1, seq)), Ok(()));
        if file.due(Some(&fc)) {
            file.save::<16>(Some(&fc), None).unwrap();
        }
    }
    file.save::<16>(Some(&fc), None).unwrap();
    // Frames sent after the last save, then a crash.
    for seq in 100..110 {
        assert_eq!(verify(&mut v, &signed(&mut fc, 1, 1, seq)), Ok(()));
    }
    let clock_back = t0 - 600 * SECOND;

    let mut without = Signer::new(KEY, 0, clock_back);
    assert_eq!(
        verify(&mut v, &signed(&mut without, 1, 1, 0)),
        Err(SignatureError::Replay)
    );

    let state = SigningState::load(&path).unwrap();
    let start = state.signer_start(clock_back);
    assert!(start > fc.timestamp(), "after all it sent");
    let mut restarted = Signer::new(KEY, 0, start);
    for seq in 0..10 {
        assert_eq!(verify(&mut v, &signed(&mut restarted, 1, 1, seq)), Ok(()));
    }
    std::fs::remove_file(&path).unwrap();
}

static RESTART_CLOCK: AtomicU64 = AtomicU64::new(0);
fn restart_clock() -> u64 {
    RESTART_CLOCK.load(Ordering::Relaxed)
}

/// The restart case on the receiving side: frames accepted before
/// the verifier's restart, replayed seconds after it, are rejected by a
/// verifier restored from its state file. A clock-started verifier without
/// the file accepts them (they are less than a minute old).
#[test]
fn a_verifier_restarted_from_its_state_rejects_replays() {
    let path = temp_path("verifier_restart");
    let t0 = 420_000_000 * SECOND;
    RESTART_CLOCK.store(t0, Ordering::Relaxed);
    let (mut file, _) = StateFile::open(&path).unwrap();
    let mut v: Verifier = file.state().verifier_with_clock(KEY, restart_clock);
    let mut fc = Signer::new(KEY, 0, t0);
    let mut gcs = Signer::new(KEY, 2, t0);
    let mut sent = Vec::new();
    for seq in 0..20 {
        sent.push(signed(&mut fc, 1, 1, seq));
        sent.push(signed(&mut gcs, 255, 190, seq));
    }
    for f in &sent {
        assert_eq!(verify(&mut v, f), Ok(()));
    }
    assert!(file.save(None, Some(&v)).unwrap());

    RESTART_CLOCK.store(t0 + 5 * SECOND, Ordering::Relaxed);
    let (file, loaded) = StateFile::open(&path).unwrap();
    assert_eq!(loaded, Loaded::Existing);
    let mut restored: Verifier = file.state().verifier_with_clock(KEY, restart_clock);
    for f in &sent {
        assert_eq!(verify(&mut restored, f), Err(SignatureError::Replay));
    }
    assert_eq!(verify(&mut restored, &signed(&mut fc, 1, 1, 20)), Ok(()));

    let mut forgetful: Verifier = Verifier::with_clock(KEY, restart_clock);
    assert_eq!(verify(&mut forgetful, &sent[0]), Ok(()));
    std::fs::remove_file(&path).unwrap();
}

/// A state as a running verifier and signer leave it: evictions (floors),
/// several streams, a signer.
fn busy_state() -> SigningState {
    let t0 = 430_000_000 * SECOND;
    let mut v = Verifier::<4>::with_timestamp(KEY, t0);
    for i in 0..9u8 {
        let mut s = Signer::new(KEY, i % 2, t0 + u64::from(i) * 1000);
        verify(&mut v, &signed(&mut s, i, 1, 0)).unwrap();
    }
    let mut signer = Signer::new(KEY, 0, t0 + 12_344);
    signed(&mut signer, 1, 1, 0);
    let state = SigningState::capture(Some(&signer), Some(&v));
    assert_eq!(state.streams.len(), 4);
    assert!(state.floors.iter().any(|&f| f != 0));
    state
}

#[test]
fn the_state_file_round_trips() {
    let state = busy_state();
    let text = state.to_text();
    assert!(text.starts_with("mavframe-signing-state 2\nsigner 43000000012345\n"));
    assert_eq!(SigningState::from_text(text.as_bytes()).unwrap(), state);
    let path = temp_path("round_trip");
    state.save(&path).unwrap();
    assert_eq!(SigningState::load(&path).unwrap(), state);
    // Saved over: replaced whole, no temporary file left.
    let empty = SigningState::default();
    empty.save(&path).unwrap();
    assert_eq!(SigningState::load(&path).unwrap(), empty);
    let dir = path.parent().unwrap();
    let name = path.file_name().unwrap().to_str().unwrap();
    let leftovers = std::fs::read_dir(dir)
        .unwrap()
        .filter(|e| {
            let n = e.as_ref().unwrap().file_name();
            let n = n.to_str().unwrap();
            n.starts_with(name) && n != name
        })
        .count();
    assert_eq!(leftovers, 0);
    std::fs::remove_file(&path).unwrap();
}

#[test]
fn a_missing_state_file_is_a_typed_error_and_a_fresh_start() {
    let path = temp_path("missing");
    assert!(matches!(
        SigningState::load(&path),
        Err(StateError::Missing)
    ));
    let (file, loaded) = StateFile::open(&path).unwrap();
    assert_eq!(loaded, Loaded::Fresh);
    assert_eq!(file.state(), &SigningState::default());
}

/// Every cut of a valid file (every length from 0) is `Truncated`.
#[test]
fn every_truncation_is_a_typed_error() {
    let text = busy_state().to_text();
    for len in 0..text.len() {
        assert!(
            matches!(
                SigningState::from_text(&text.as_bytes()[..len]),
                Err(StateError::Truncated)
            ),
            "cut at {len}: {:?}",
            SigningState::from_text(&text.as_bytes()[..len])
        );
    }
}

/// Every single-bit flip of a valid file is an error, never a state with
/// other timestamps (and never a panic).
#[test]
fn every_bit_flip_is_a_typed_error() {
    let text = busy_state().to_text().into_bytes();
    for i in 0..text.len() * 8 {
        let mut bad = text.clone();
        bad[i / 8] ^= 1 << (i % 8);
        let got = SigningState::from_text(&bad);
        assert!(got.is_err(), "bit {i}: {got:?}");
    }
}

/// Random edits of a valid file (bytes replaced, inserted, removed, lines
/// swapped) and random bytes: never a panic; whatever parses is a state
/// whose file text is exactly the input.
#[test]
fn random_damage_never_panics() {
    let text = busy_state().to_text().into_bytes();
    let mut seed = 0x2545_f491_4f6c_dd1du64;
    let mut next = move || {
        seed ^= seed << 13;
        seed ^= seed >> 7;
        seed ^= seed << 17;
        seed
    };
    for _ in 0..20_000 {
        let mut bad = text.clone();
        for _ in 0..1 + next() % 4 {
            let at = (next() as usize) % bad.len().max(1);
            match next() % 4 {
                0 if !bad.is_empty() => bad[at] = next() as u8,
                1 => bad.insert(at.min(bad.len()), next() as u8),
                2 if !bad.is_empty() => {
                    bad.remove(at);
                }
                _ => bad = (0..next() % 300).map(|_| next() as u8).collect(),
            }
        }
        if let Ok(state) = SigningState::from_text(&bad) {
            assert_eq!(state.to_text().as_bytes(), &bad[..]);
        }
    }
}

#[test]
fn corrupt_files_give_typed_errors() {
    let load = |bytes: &[u8]| SigningState::from_text(bytes);
    assert!(matches!(
        load(b"hello\nworld\n"),
        Err(StateError::Corrupt { line: 1, .. })
    ));
    assert!(matches!(
        load(b"mavframe-signing-state 3\nwhatever\n"),
        Err(StateError::UnsupportedVersion(3))
    ));
    assert!(matches!(
        load(&[0xff; 100]),
        Err(StateError::Corrupt { line: 1, .. })
    ));
    // A changed digit, the checksum left: damaged.
    let text = busy_state().to_text().replacen("newest 4", "newest 3", 1);
    assert!(matches!(load(text.as_bytes()), Err(StateError::Checksum)));
    // Well-formed checksums over malformed lines (a file written by hand).
    for (body, line) in [
        ("mavframe-signing-state 1\nsigner x\n", 2),
        ("mavframe-signing-state 1\nsigner none\nnewest 1\n", 4),
        ("mavframe-signing-state 1\nsigner none\nnewest 1\nfloors 1 2\n", 4),
        (
            "mavframe-signing-state 1\nsigner 281474976710656\nnewest 1\n",
            2,
        ),
        (
            "mavframe-signing-state 1\nsigner none\nnewest 1\nfloors 0 0 0 0 0 0 0 0 0 0 0 0 0 0 0 0\nstream 0 1 256 5\n",
            5,
        ),
        (
            "mavframe-signing-state 1\nsigner none\nnewest 1\nfloors 0 0 0 0 0 0 0 0 0 0 0 0 0 0 0 0\nstream 0 1 1 -5\n",
            5,
        ),
    ] {
        let file = with_check(body);
        match load(file.as_bytes()) {
            Err(StateError::Corrupt { line: l, .. }) => assert_eq!(l, line, "{body:?}"),
            other => panic!("{body:?}: {other:?}"),
        }
    }
    let ok = "mavframe-signing-state 1\nsigner none\nnewest 1\nfloors 0 0 0 0 0 0 0 0 0 0 0 0 0 0 0 0\nstream 0 1 1 5\n";
    assert_eq!(load(with_check(ok).as_bytes()).unwrap().streams.len(), 1);
}

/// `body` followed by its check line, as `to_text` computes it (the test's
/// own SHA-256, from the same crate the format names).
fn with_check(body: &str) -> String {
    use sha2::{Digest, Sha256};
    let d = Sha256::digest(body.as_bytes());
    let hex: String = d[..8].iter().map(|b| format!("{b:02x}")).collect();
    format!("{body}check {hex}\n")
}

#[test]
fn paths_that_are_not_files_give_typed_errors() {
    let dir = PathBuf::from(env!("CARGO_TARGET_TMPDIR"));
    assert!(matches!(
        SigningState::load(&dir),
        Err(StateError::NotAFile)
    ));
    #[cfg(unix)]
    assert!(matches!(
        SigningState::load("/dev/null"),
        Err(StateError::NotAFile)
    ));
    let big = temp_path("too_large");
    std::fs::write(&big, vec![b'a'; 100 * 1024]).unwrap();
    assert!(matches!(
        SigningState::load(&big),
        Err(StateError::TooLarge { len: 102_400 })
    ));
    std::fs::remove_file(&big).unwrap();
    // Saving into a directory that does not exist: an I/O error.
    let nowhere = dir.join("no-such-dir").join("state");
    assert!(matches!(
        SigningState::default().save(&nowhere),
        Err(StateError::Io(_))
    ));
}

/// The save policy: nothing is due before the signer signs; then due at
/// once, and again once it signed within half the margin of the saved
/// bound; a restored signer starts past anything signed before that, even
/// the frame that made it due (a crash before that save).
#[test]
fn checkpoints_come_before_the_signer_outruns_the_margin() {
    let path = temp_path("margin");
    let (file, _) = StateFile::open(&path).unwrap();
    let mut file = file.with_interval(std::time::Duration::from_secs(3600));
    let mut signer = Signer::new(KEY, 0, 1_000_000_000);
    assert!(!file.due(Some(&signer)), "nothing signed: nothing to keep");
    signed(&mut signer, 1, 1, 0);
    assert!(file.due(Some(&signer)), "signed, never saved");
    assert!(file.save::<16>(Some(&signer), None).unwrap());
    assert_eq!(
        file.state().signer,
        Some(signer.signed_below() + SIGNER_MARGIN)
    );
    assert!(!file.due(Some(&signer)));
    assert!(!file.save::<16>(Some(&signer), None).unwrap(), "unchanged");
    while !file.due(Some(&signer)) {
        signer.advance_to(signer.timestamp() + 997);
        signed(&mut signer, 1, 1, 0);
    }
    let start = SigningState::load(&path).unwrap().signer_start(0);
    assert!(start >= signer.signed_below(), "past every frame signed");
    std::fs::remove_file(&path).unwrap();
}

/// A file that cannot be written: the save fails, and the next is due
/// only an interval later, however far the signer runs ahead (it was tried
/// again at every frame, each an attempt to create a file).
#[test]
fn a_failed_save_is_tried_again_an_interval_later() {
    let dir = temp_path("unwritable-dir");
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("no-such-dir").join("state");
    let (file, loaded) = StateFile::open(&path).unwrap();
    assert_eq!(loaded, Loaded::Fresh);
    let interval = std::time::Duration::from_millis(300);
    let mut file = file.with_interval(interval);
    let mut signer = Signer::new(KEY, 0, 1_000_000_000);
    signed(&mut signer, 1, 1, 0);
    assert!(file.due(Some(&signer)));
    assert!(matches!(
        file.save::<16>(Some(&signer), None),
        Err(StateError::Io(_))
    ));
    signer.advance_to(signer.timestamp() + 10 * SIGNER_MARGIN);
    signed(&mut signer, 1, 1, 1);
    assert!(!file.due(Some(&signer)), "tried again at once");
    std::thread::sleep(interval);
    assert!(file.due(Some(&signer)), "never tried again");
    std::fs::remove_dir_all(&dir).unwrap();
}

/// The spec's window, exactly: a new stream one minute behind is accepted,
/// one tick more is not.
#[test]
fn the_new_stream_window_is_one_minute() {
    let now = 450_000_000 * SECOND;
    let mut v: Verifier = Verifier::with_timestamp(KEY, now);
    let mut edge = Signer::new(KEY, 0, now - NEW_STREAM_WINDOW);
    assert_eq!(verify(&mut v, &signed(&mut edge, 1, 1, 0)), Ok(()));
    let mut late = Signer::new(KEY, 0, now - NEW_STREAM_WINDOW - 1);
    assert_eq!(
        verify(&mut v, &signed(&mut late, 2, 1, 0)),
        Err(SignatureError::TooOld)
    );
}

/// A version 1 file (whose `signer` was the next timestamp, the margin
/// added at restart) is read as the bound a version 1 reader started from,
/// and written back as version 2.
#[test]
fn a_version_1_file_is_read_with_its_margin() {
    let v1 =
        "mavframe-signing-state 1\nsigner 1000\nnewest 5\nfloors 0 0 0 0 0 0 0 0 0 0 0 0 0 0 0 0\n";
    let state = SigningState::from_text(with_check(v1).as_bytes()).unwrap();
    assert_eq!(
        (state.signer, state.newest),
        (Some(1000 + SIGNER_MARGIN), 5)
    );
    assert!(state
        .to_text()
        .starts_with("mavframe-signing-state 2\nsigner 1001000\n"));
    assert_eq!(state.signer_start(0), 1000 + SIGNER_MARGIN);
}

// ------------------------------------------------------ restarts and drift

/// One run of a program with a state file at `path` whose clock reads
/// `now` (and does not move while it runs): it signs `frames` frames, saving
/// as the recommended loop does, and exits cleanly (`save_final`) or
/// crashes (no save after its last frame). Returns its signer.
fn run(path: &std::path::Path, now: u64, frames: u8, clean: bool) -> Signer {
    let (mut file, _) = StateFile::open(path).unwrap();
    let mut signer = file.state().signer_at(KEY, 0, now);
    let before = file.state().signer.unwrap_or(0);
    assert!(signer.timestamp() >= before, "never below what was signed");
    for seq in 0..frames {
        signer.advance_to(now);
        signed(&mut signer, 1, 1, seq);
        if clean && file.due(Some(&signer)) {
            file.save::<16>(Some(&signer), None).unwrap();
        }
    }
    if clean {
        file.save_final::<16>(Some(&signer), None).unwrap();
    }
    signer
}

/// Restarts that sign nothing leave the signer's bound where it was,
/// whether they exit cleanly or crash after a periodic save, however many
/// and however quick: a restarted signer starts from the clock once the
/// clock passed what was signed. (The old rule moved it 10 s ahead of the
/// clock at each restart: 65 s after 7 quick ones.)
#[test]
fn restarts_that_sign_nothing_do_not_move_the_signer() {
    let path = temp_path("idle_restarts");
    let t0 = 460_000_000 * SECOND;
    let first = run(&path, t0, 3, true);
    let bound = SigningState::load(&path).unwrap().signer;
    assert_eq!(bound, Some(first.signed_below()), "exactly what was signed");
    for k in 0..7u64 {
        let now = t0 + k * 1000;
        let (mut file, _) = StateFile::open(&path).unwrap();
        let signer = file.state().signer_at(KEY, 0, now);
        assert!(
            !file.due(Some(&signer)),
            "restart {k}: nothing signed, nothing due"
        );
        // A periodic save (the verifier changed), then a clean exit or not.
        file.save::<16>(Some(&signer), None).unwrap();
        if k % 2 == 0 {
            file.save_final::<16>(Some(&signer), None).unwrap();
        }
        assert_eq!(
            SigningState::load(&path).unwrap().signer,
            bound,
            "restart {k}"
        );
    }
    let later = t0 + SECOND;
    let state = SigningState::load(&path).unwrap();
    assert_eq!(state.signer_start(later), later, "the clock again");
    std::fs::remove_file(&path).unwrap();
}

/// Seven quick clean restarts, each signing frames (heartbeats) with the
/// clock standing still: each starts just above what the one before
/// signed, so the signer is ahead of the clock by the frames signed (35
/// ticks, 0.35 ms), not by a margin per restart.
#[test]
fn quick_clean_restarts_that_sign_do_not_drift_ahead() {
    let path = temp_path("quick_restarts");
    let now = 470_000_000 * SECOND;
    let mut signed_before = 0;
    for k in 0..7 {
        let signer = run(&path, now, 5, true);
        assert!(
            signer.signed_below() > signed_before,
            "restart {k} went back"
        );
        signed_before = signer.signed_below();
    }
    let start = SigningState::load(&path).unwrap().signer_start(now);
    assert_eq!(
        start,
        now + 35,
        "ahead of the clock by more than the frames signed"
    );
    std::fs::remove_file(&path).unwrap();
}

/// A crash after signing: the frames signed since the last save are
/// covered by the checkpoint's margin, so the restart starts above every
/// frame signed, even with the clock gone back to 1970; and no further
/// than the margin above the last frame signed.
#[test]
fn a_crash_after_signing_restarts_above_every_frame_signed() {
    let path = temp_path("crash");
    let t0 = 480_000_000 * SECOND;
    let (mut file, _) = StateFile::open(&path).unwrap();
    let mut signer = file.state().signer_at(KEY, 0, t0);
    let mut v: Verifier = Verifier::with_timestamp(KEY, t0);
    // Four seconds of frames at 20 Hz, saved as the loop does; the crash
    // comes before the save after the last of them.
    for i in 0..80u64 {
        signer.advance_to(t0 + i * SECOND / 20);
        assert_eq!(verify(&mut v, &signed(&mut signer, 1, 1, i as u8)), Ok(()));
        if i < 79 && file.due(Some(&signer)) {
            file.save::<16>(Some(&signer), None).unwrap();
        }
    }
    drop(file);
    let state = SigningState::load(&path).unwrap();
    let start = state.signer_start(0);
    assert!(start >= signer.signed_below(), "above every frame signed");
    assert!(start <= signer.signed_below() + SIGNER_MARGIN);
    let mut restarted = state.signer_at(KEY, 0, 0);
    assert_eq!(verify(&mut v, &signed(&mut restarted, 1, 1, 0)), Ok(()));
    std::fs::remove_file(&path).unwrap();
}

// ------------------------------------------------------------ clock skews

/// `META`'s notice, as a message of a one-message dialect, for parsers and
/// connections.
#[derive(Debug, Clone, Default, PartialEq)]
struct Notice([u8; 12]);

impl MessageData for Notice {
    const META: MessageMeta = META;
    type View<'a> = &'a [u8];
    fn parse(p: &[u8]) -> Self {
        let mut b = [0; 12];
        let n = p.len().min(12);
        b[..n].copy_from_slice(&p[..n]);
        Notice(b)
    }
    fn emit(&self, p: &mut [u8]) -> Result<usize, BufferTooSmall> {
        let got = p.len();
        p.get_mut(..12)
            .ok_or(BufferTooSmall { needed: 12, got })?
            .copy_from_slice(&self.0);
        Ok(12)
    }
    fn view(p: &[u8]) -> &[u8] {
        p
    }
}

struct Notices;

impl MessageSet for Notices {
    type Message = Notice;
    type View<'a> = &'a [u8];
    const MESSAGES: &'static [MessageMeta] = &[META];
    fn parse(id: u32, p: &[u8]) -> Option<Notice> {
        (id == META.id).then(|| Notice::parse(p))
    }
    fn view(id: u32, p: &[u8]) -> Option<&[u8]> {
        (id == META.id).then_some(p)
    }
}

fn timestamp_of(frame: &[u8]) -> u64 {
    Frame::new_checked(frame)
        .unwrap()
        .signature()
        .unwrap()
        .timestamp()
}

/// One side of a link as the front ends run it, on a clock of its own: a
/// parser verifying with the link's key (the verifier reading the clock),
/// and a framer whose signer keeps up with the clock and adopts what the
/// verifier accepted.
struct Node {
    parser: Parser<Notices>,
    framer: Framer,
    ids: (u8, u8),
}

impl Node {
    fn new(clock: fn() -> u64, ids: (u8, u8)) -> Node {
        let mut framer = Framer::new();
        framer.set_clock(Some(clock));
        framer.set_signer(Some(Signer::new(KEY, 0, clock())));
        let verifier = Verifier::with_clock(KEY, clock);
        let parser = Parser::with_signing(verifier, Unsigned::Refuse);
        Node {
            parser,
            framer,
            ids,
        }
    }

    fn send(&mut self) -> Vec<u8> {
        let (sysid, compid) = self.ids;
        let frame = self.framer.frame(sysid, compid, &Notice([7; 12]));
        frame.unwrap().to_vec()
    }

    /// Whether the frame in `datagram` is accepted (authenticated); then
    /// the signer adopts, as the front ends do.
    fn recv(&mut self, datagram: &[u8]) -> bool {
        let mut input = datagram;
        let mut ok = self.parser.next_in_datagram(&mut input).is_some();
        ok |= self.parser.end_of_datagram().is_some();
        self.framer.adopt_from(self.parser.verifier());
        ok
    }

    fn stats(&self) -> Stats {
        *self.parser.stats()
    }

    fn next_timestamp(&self) -> u64 {
        self.framer.signer().unwrap().timestamp()
    }
}

static CC_CLOCK: AtomicU64 = AtomicU64::new(0);
static FC_CLOCK: AtomicU64 = AtomicU64::new(0);
fn cc_clock() -> u64 {
    CC_CLOCK.load(Ordering::Relaxed)
}
fn fc_clock() -> u64 {
    FC_CLOCK.load(Ordering::Relaxed)
}

/// The skews the daemons were run with (the companion an hour behind, an
/// hour ahead, 70 s behind, in 1970), against a correctly clocked FC. The
/// side behind has its first frame refused as stale (a timestamp refusal,
/// never a bad signature); one frame of the side ahead is accepted (from
/// the future) and adopted; from then on every frame is accepted both
/// ways, the side behind signing at the other's time, and the early frame
/// stays refused.
#[test]
fn a_clock_skew_ends_with_the_first_frame_of_the_side_ahead() {
    let real = 440_000_000 * SECOND;
    for (name, cc) in [
        ("CC 1 h behind", real - HOUR),
        ("CC 1 h ahead", real + HOUR),
        ("CC 70 s behind", real - 70 * SECOND),
        ("CC in 1970", 0),
    ] {
        CC_CLOCK.store(cc, Ordering::Relaxed);
        FC_CLOCK.store(real, Ordering::Relaxed);
        let mut cc_node = Node::new(cc_clock, (1, 191));
        let mut fc_node = Node::new(fc_clock, (1, 1));
        let (ahead, behind) = match cc > real {
            true => (&mut cc_node, &mut fc_node),
            false => (&mut fc_node, &mut cc_node),
        };
        let early = behind.send();
        assert!(!ahead.recv(&early), "{name}: more than a minute behind");
        let s = ahead.stats();
        assert_eq!((s.stale_timestamp, s.bad_signature), (1, 0), "{name}");

        let first = ahead.send();
        assert!(behind.recv(&first), "{name}: the side ahead is accepted");
        assert!(behind.next_timestamp() >= timestamp_of(&first), "{name}");
        for i in 0..5 {
            CC_CLOCK.fetch_add(SECOND, Ordering::Relaxed);
            FC_CLOCK.fetch_add(SECOND, Ordering::Relaxed);
            let b = behind.send();
            assert!(ahead.recv(&b), "{name}: frame {i} of the side behind");
            let a = ahead.send();
            assert!(behind.recv(&a), "{name}: frame {i} of the side ahead");
        }
        assert!(!ahead.recv(&early), "{name}: a replay now");
        for node in [&cc_node, &fc_node] {
            assert_eq!(node.stats().bad_signature, 0, "{name}");
        }
        assert_eq!(cc_node.stats().frames + fc_node.stats().frames, 11);
    }
}

static ONE_CLOCK: AtomicU64 = AtomicU64::new(0);
fn one_clock() -> u64 {
    ONE_CLOCK.load(Ordering::Relaxed)
}

/// The signer adopts only what its verifier accepted: a frame from the
/// future signed with another key moves nothing (a bad signature), nor does
/// a replay (stale); a correctly signed frame years ahead is accepted (no
/// upper bound) and adopted. It never goes back: adopting an older
/// timestamp changes nothing, and its frames' timestamps keep increasing.
#[test]
fn a_signer_adopts_only_verified_timestamps_and_never_goes_back() {
    let t = 445_000_000 * SECOND;
    ONE_CLOCK.store(t, Ordering::Relaxed);
    let mut node = Node::new(one_clock, (1, 191));
    let before = node.next_timestamp();
    let years = 10 * 365 * 24 * HOUR;

    let mut forger = Signer::new([9; 32], 0, t + years);
    assert!(!node.recv(&signed(&mut forger, 1, 1, 0)));
    assert_eq!(node.stats().bad_signature, 1);
    assert_eq!(node.next_timestamp(), before, "a forgery moves nothing");

    let mut ahead = Signer::new(KEY, 0, t + years);
    let genuine = signed(&mut ahead, 1, 1, 0);
    assert!(node.recv(&genuine), "from the future, correctly signed");
    assert_eq!(node.next_timestamp(), t + years);
    assert!(!node.recv(&genuine));
    assert_eq!(node.stats().stale_timestamp, 1);
    assert_eq!(node.next_timestamp(), t + years);

    node.framer.adopt(t);
    assert_eq!(node.next_timestamp(), t + years, "never back");
    let mut last = 0;
    for _ in 0..3 {
        let ts = timestamp_of(&node.send());
        assert!(ts >= t + years && ts > last);
        last = ts;
    }
}

/// After adopting a correctly clocked FC's time (its own clock an hour
/// behind), a CC restarted from its state file still refuses every replay
/// of the FC's frames, and signs from where it was: the FC accepts its
/// first frame after the restart, though the CC's clock is still behind.
#[test]
fn replays_stay_refused_after_adoption_and_a_restart() {
    let path = temp_path("adopted_restart");
    let real = 490_000_000 * SECOND;
    CC_RESTART_CLOCK.store(real - HOUR, Ordering::Relaxed);
    FC_RESTART_CLOCK.store(real, Ordering::Relaxed);
    let mut fc = Node::new(restart_fc_clock, (1, 1));
    let (mut file, _) = StateFile::open(&path).unwrap();
    let mut cc = Node::new(restart_cc_clock, (1, 191));
    let fc_frames: Vec<Vec<u8>> = (0..5).map(|_| fc.send()).collect();
    for f in &fc_frames {
        assert!(cc.recv(f));
    }
    assert!(fc.recv(&cc.send()), "the CC signs at the FC's time");
    assert!(!cc.recv(&fc_frames[2]));
    file.save_final(cc.framer.signer(), cc.parser.verifier())
        .unwrap();
    assert!(file.state().signer.unwrap() > real, "the FC's time");

    let (file, _) = StateFile::open(&path).unwrap();
    let verifier = file.state().verifier_with_clock(KEY, restart_cc_clock);
    let mut restarted = Node::new(restart_cc_clock, (1, 191));
    restarted.parser = Parser::with_signing(verifier, Unsigned::Refuse);
    let signer = file.state().signer_at(KEY, 0, real - HOUR);
    restarted.framer.set_signer(Some(signer));
    for f in &fc_frames {
        assert!(!restarted.recv(f), "a replay after the restart");
    }
    let s = restarted.stats();
    assert_eq!((s.stale_timestamp, s.bad_signature), (5, 0));
    assert!(fc.recv(&restarted.send()), "on from where it was");
    std::fs::remove_file(&path).unwrap();
}

static CC_RESTART_CLOCK: AtomicU64 = AtomicU64::new(0);
static FC_RESTART_CLOCK: AtomicU64 = AtomicU64::new(0);
fn restart_cc_clock() -> u64 {
    CC_RESTART_CLOCK.load(Ordering::Relaxed)
}
fn restart_fc_clock() -> u64 {
    FC_RESTART_CLOCK.load(Ordering::Relaxed)
}

// ------------------------------------------------- over 127.0.0.1 (UDP)

/// A clock an hour ahead of the system's.
fn hour_ahead() -> u64 {
    timestamp_now() + HOUR
}

/// A connection on `endpoint` with the key, refusing unsigned frames;
/// `ahead`: its signer and verifier an hour ahead of the system clock.
fn signed_connection(endpoint: &str, ahead: bool) -> Connection<Notices> {
    let transport = mavframe::conn::open(&endpoint.parse().unwrap()).unwrap();
    let (verifier, start) = match ahead {
        true => (Verifier::with_clock(KEY, hour_ahead), hour_ahead()),
        false => (Verifier::starting_now(KEY), timestamp_now()),
    };
    let parser = Parser::with_signing(verifier, Unsigned::Refuse);
    let mut conn = Connection::with_parser(transport, parser);
    conn.set_signer(Some(Signer::new(KEY, 0, start)));
    conn
}

const WAIT: Option<Duration> = Some(Duration::from_secs(5));

/// A `udpin` connection (the CC, as the daemons run it) and a `udpout` one
/// (the FC) over 127.0.0.1, the FC's clock an hour ahead. The FC is heard
/// first: the CC accepts its frame (from the future) and, through its
/// split halves (the sending half on another thread), signs at the FC's
/// time; from then on frames are accepted both ways.
#[test]
fn udp_connections_follow_the_side_ahead() {
    let cc = signed_connection("udpin:127.0.0.1:0", false);
    let port = cc.transport().local_addr().unwrap().port();
    let mut fc = signed_connection(&format!("udpout:127.0.0.1:{port}"), true);
    let (mut cc_tx, mut cc_rx) = cc.split().unwrap();
    fc.send_auto(1, 1, &Notice([1; 12])).unwrap();
    let first = cc_rx.recv(WAIT).unwrap().expect("the FC's frame");
    assert!(first.is_authenticated());
    let fc_time = first.frame().signature().unwrap().timestamp();
    let sender = std::thread::spawn(move || {
        for i in 0..5 {
            cc_tx.send_auto(1, 191, &Notice([i; 12])).unwrap();
        }
        cc_tx
    });
    for i in 0..5 {
        let got = fc.recv(WAIT).unwrap().expect("the CC's frame");
        assert!(got.is_authenticated(), "frame {i}");
        assert!(got.frame().signature().unwrap().timestamp() >= fc_time);
        fc.send_auto(1, 1, &Notice([i; 12])).unwrap();
        assert!(cc_rx.recv(WAIT).unwrap().unwrap().is_authenticated());
    }
    sender.join().unwrap();
    for stats in [fc.stats(), cc_rx.stats()] {
        assert_eq!((stats.stale_timestamp, stats.bad_signature), (0, 0));
    }
}

/// The other way round: the CC (`udpin`) an hour ahead. The FC's frames
/// are refused as stale (not as bad signatures) and the CC, having
/// accepted nobody, answers nobody: a listener ahead must be heard first.
/// Given its peer (as `--peer` does), it is: the FC adopts its time, and
/// frames are accepted both ways.
#[test]
fn a_udp_listener_ahead_must_be_heard_first() {
    let mut cc = signed_connection("udpin:127.0.0.1:0", true);
    let port = cc.transport().local_addr().unwrap().port();
    let mut fc = signed_connection(&format!("udpout:127.0.0.1:{port}"), false);
    fc.send_auto(1, 1, &Notice([1; 12])).unwrap();
    let short = Some(Duration::from_millis(300));
    assert!(cc.recv(short).unwrap().is_none(), "refused");
    let s = *cc.stats();
    assert_eq!((s.stale_timestamp, s.bad_signature), (1, 0));
    cc.send_auto(1, 191, &Notice([2; 12])).unwrap();
    assert!(fc.recv(short).unwrap().is_none(), "no peer to answer");

    let fc_addr = fc.transport().local_addr().unwrap();
    let AnyTransport::UdpIn(udpin) = cc.transport_mut() else {
        panic!("udpin");
    };
    udpin.set_reply_to(ReplyTo::Fixed(fc_addr));
    cc.send_auto(1, 191, &Notice([3; 12])).unwrap();
    let got = fc.recv(WAIT).unwrap().expect("the CC's frame");
    assert!(got.is_authenticated());
    for i in 0..5 {
        fc.send_auto(1, 1, &Notice([i; 12])).unwrap();
        assert!(
            cc.recv(WAIT).unwrap().unwrap().is_authenticated(),
            "frame {i}"
        );
        cc.send_auto(1, 191, &Notice([i; 12])).unwrap();
        assert!(fc.recv(WAIT).unwrap().unwrap().is_authenticated());
    }
    assert_eq!(cc.stats().bad_signature + fc.stats().bad_signature, 0);
}

/// A router's `udpin` and `tcpin` links (on the system clock; `tcpin`'s
/// clients share one verifier) and a peer an hour ahead (its signer and
/// verifier): the link accepts the peer's frame and signs its own next
/// message at the peer's time, which the peer accepts.
#[cfg(feature = "tokio")]
#[tokio::test]
async fn router_links_adopt_the_time_of_a_peer_ahead() {
    use mavframe::route::Links;
    use mavframe::router::{Inbound, LinkConfig, Out, Policy, Router};
    /// Tells the test whether each frame was authenticated, and answers
    /// its sender.
    struct Seen(tokio::sync::mpsc::UnboundedSender<bool>);
    impl Policy<Notices> for Seen {
        fn frame(&mut self, inbound: &Inbound<'_, Notices>, out: &mut Out<'_>) {
            let _ = self.0.send(inbound.frame.is_authenticated());
            if let Some(source) = inbound.source {
                out.set_peers(inbound.link, &[source]);
            }
        }
    }
    for (listen, connect) in [("udpin", "udpout"), ("tcpin", "tcp")] {
        let probe = std::net::TcpListener::bind("127.0.0.1:0").unwrap();
        let addr = probe.local_addr().unwrap();
        drop(probe);
        let (tx, mut seen) = tokio::sync::mpsc::unbounded_channel();
        let mut router = Router::<Notices, _>::new(Seen(tx));
        let mut config = LinkConfig::new(format!("{listen}:{addr}").parse().unwrap());
        (config.key, config.unsigned) = (Some(KEY), Unsigned::Refuse);
        let link = router.add(config).await.unwrap();
        let mut peer = signed_connection(&format!("{connect}:{addr}"), true);
        peer.send_auto(1, 191, &Notice([1; 12])).unwrap();
        let peer_time = hour_ahead() - SECOND;
        let got = tokio::time::timeout(Duration::from_secs(5), seen.recv()).await;
        let Ok(Some(authenticated)) = got else {
            panic!("{listen}: no frame");
        };
        assert!(authenticated, "{listen}");
        router.with(|_, out| out.send_message(Links::only(link), 1, 1, &Notice([2; 12])));
        let got = tokio::task::spawn_blocking(move || {
            let got = peer.recv(WAIT).unwrap();
            (got, *peer.stats())
        });
        let (got, stats) = got.await.unwrap();
        let got = got.unwrap_or_else(|| panic!("{listen}: no frame from the link: {stats:?}"));
        assert!(got.is_authenticated(), "{listen}");
        assert!(got.frame().signature().unwrap().timestamp() >= peer_time);
        router.shutdown(Duration::from_secs(1)).await;
    }
}

/// The verifier's state after an eviction, saved and restored (as across a
/// restart): the evicted stream's frames stay out, by its bucket's floor.
#[test]
fn an_evicted_streams_frames_stay_out_across_a_restart() {
    let t0 = 440_000_000 * SECOND;
    let mut v = Verifier::<1>::with_timestamp(KEY, t0);
    let mut fc = Signer::new(KEY, 0, t0);
    let sent: Vec<Vec<u8>> = (0..5).map(|i| signed(&mut fc, 1, 1, i)).collect();
    for f in &sent {
        assert_eq!(verify(&mut v, f), Ok(()));
    }
    let mut gcs = Signer::new(KEY, 1, fc.timestamp() + 10);
    assert_eq!(verify(&mut v, &signed(&mut gcs, 255, 190, 0)), Ok(()));
    assert!(v.floors().iter().any(|&f| f >= fc.timestamp() - 1));

    let state = SigningState::capture(None, Some(&v));
    let mut restored = Verifier::<1>::with_timestamp(KEY, t0);
    state.restore_into(&mut restored);
    assert_eq!(restored.floors(), v.floors());
    for f in &sent {
        assert_eq!(verify(&mut restored, f), Err(SignatureError::BelowFloor));
    }
}

/// The floor buckets hash every part of a stream's key, so that evicted
/// streams that differ only in their link id, or only in their system id,
/// raise many floors, not one (one would hold back every new stream).
#[test]
fn evicted_streams_spread_over_the_floor_buckets() {
    let t0 = 450_000_000 * SECOND;
    let raised = |key: &dyn Fn(u8) -> (u8, u8)| {
        let mut v = Verifier::<1>::with_timestamp(KEY, t0);
        for i in 0..33u8 {
            let (link_id, sysid) = key(i);
            let mut s = Signer::new(KEY, link_id, t0 + u64::from(i) * 10);
            assert_eq!(verify(&mut v, &signed(&mut s, sysid, 1, 0)), Ok(()));
        }
        v.floors().iter().filter(|&&f| f != 0).count()
    };
    let by_link = raised(&|i| (i, 1));
    let by_system = raised(&|i| (0, i + 1));
    assert!(by_link >= 8 && by_system >= 8, "{by_link} {by_system}");
}

/// A verifier's debug output says what it holds, and never its key.
#[test]
fn a_verifiers_debug_output_never_shows_its_key() {
    let t0 = 460_000_000 * SECOND;
    let mut v = Verifier::<4>::with_timestamp(KEY, t0);
    let mut fc = Signer::new(KEY, 0, t0);
    assert_eq!(verify(&mut v, &signed(&mut fc, 1, 1, 0)), Ok(()));
    let text = format!("{v:?}");
    assert!(text.contains("streams: 1"), "{text}");
    let key_text = String::from_utf8_lossy(&KEY);
    assert!(
        !text.contains(&*key_text) && !text.contains("109, 97, 118"),
        "{text}"
    );
}

/// The timestamp rules run before the signature is computed: a capture
/// too old for a new stream, or below its bucket's floor, is refused as
/// stale whatever its signature (a keyless flood of old timestamps costs a
/// look-up, not a SHA-256), while a fresh one with another key's signature
/// is a mismatch.
#[test]
fn the_timestamp_rules_refuse_before_the_signature_is_checked() {
    let t0 = 470_000_000 * SECOND;
    let other_key = [7u8; 32];
    let mut v = Verifier::<1>::with_timestamp(KEY, t0);
    let mut old = Signer::new(other_key, 0, t0 - 2 * NEW_STREAM_WINDOW);
    assert_eq!(
        verify(&mut v, &signed(&mut old, 1, 1, 0)),
        Err(SignatureError::TooOld)
    );
    let mut fresh = Signer::new(other_key, 0, t0);
    assert_eq!(
        verify(&mut v, &signed(&mut fresh, 1, 1, 0)),
        Err(SignatureError::Mismatch)
    );

    let mut fc = Signer::new(KEY, 0, t0 + 100);
    assert_eq!(verify(&mut v, &signed(&mut fc, 1, 1, 0)), Ok(()));
    let mut gcs = Signer::new(KEY, 1, t0 + 200);
    assert_eq!(verify(&mut v, &signed(&mut gcs, 255, 190, 0)), Ok(()));
    let mut below = Signer::new(other_key, 0, t0 + 50);
    let frame = signed(&mut below, 1, 1, 1);
    assert_eq!(verify(&mut v, &frame), Err(SignatureError::BelowFloor));
    assert!(verify(&mut v, &frame).unwrap_err().is_stale());
}
