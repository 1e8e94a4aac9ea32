//! Signing across restarts and under stream floods (issue 10, item 4): a
//! fresh verifier rejects old captures, the stream table evicts without a
//! replay hole or a lock-out, and the state file carries the signer's and
//! the verifier's timestamps over a restart.
#![cfg(feature = "std")]

use mavframe::frame::{finish, Frame, Header, Version, MAX_FRAME_LEN};
use mavframe::message::MessageMeta;
use mavframe::signing::state::{Loaded, SigningState, StateError, StateFile, SIGNER_MARGIN};
use mavframe::signing::{timestamp_now, SignatureError, Signer, Verifier, NEW_STREAM_WINDOW};
use std::path::PathBuf;
use std::sync::atomic::{AtomicU64, Ordering};

const KEY: [u8; 32] = *b"mavframe-signing-state-test-key!";

/// 10 µs units.
const SECOND: u64 = 100_000;

const META: MessageMeta = MessageMeta {
    id: 15001,
    name: "TEST_NOTICE",
    crc_extra: 77,
    min_len: 12,
    max_len: 12,
    target_system_offset: None,
    target_component_offset: None,
    fields: &[],
};

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

/// The case: 50 captured notices, replayed into a freshly started
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

/// The case: 16 other signers of the key take every slot, then the
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

/// The case: a signer restarts with its clock 600 s behind. Without
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
    let signer = Signer::new(KEY, 0, t0 + 12_345);
    let state = SigningState::capture(Some(&signer), Some(&v));
    assert_eq!(state.streams.len(), 4);
    assert!(state.floors.iter().any(|&f| f != 0));
    state
}

#[test]
fn the_state_file_round_trips() {
    let state = busy_state();
    let text = state.to_text();
    assert!(text.starts_with("mavframe-signing-state 1\nsigner 43000000012345\n"));
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
        load(b"mavframe-signing-state 2\nwhatever\n"),
        Err(StateError::UnsupportedVersion(2))
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

/// The save policy: due once the signer ran half the margin past the saved
/// timestamp, and a restored signer starts past anything sent before that.
#[test]
fn saves_come_before_the_signer_outruns_the_margin() {
    let path = temp_path("margin");
    let (mut file, _) = StateFile::open(&path).unwrap();
    let file_interval = std::time::Duration::from_secs(3600);
    file = file.with_interval(file_interval);
    let mut signer = Signer::new(KEY, 0, 1_000_000_000);
    assert!(file.due(Some(&signer)), "never saved");
    assert!(file.save::<16>(Some(&signer), None).unwrap());
    assert!(!file.due(Some(&signer)));
    assert!(!file.save::<16>(Some(&signer), None).unwrap(), "unchanged");
    let mut highest_sent = 0;
    while !file.due(Some(&signer)) {
        highest_sent = signer.timestamp();
        signer.advance_to(signer.timestamp() + 997);
        signed(&mut signer, 1, 1, 0);
    }
    let start = SigningState::load(&path).unwrap().signer_start(0);
    assert!(start > highest_sent && start >= 1_000_000_000 + SIGNER_MARGIN);
    assert!(
        start > signer.timestamp(),
        "even the frame that made it due"
    );
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
    assert!(file.due(Some(&signer)));
    assert!(matches!(
        file.save::<16>(Some(&signer), None),
        Err(StateError::Io(_))
    ));
    signer.advance_to(signer.timestamp() + 10 * SIGNER_MARGIN);
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
