//! `mavgen-rs check` on paths and include graphs that must give a clear
//! error (or a clear success), never a hang, an out-of-memory kill or a
//! stack overflow: devices, FIFOs, directories, oversized files, include
//! chains and cycles thousands of files deep, deeply nested XML, files cut
//! short (an interrupted copy, a half-written download).
//!
//! The binary runs under a memory cap and a deadline, so a regression fails
//! the test instead of taking the machine down or hanging the run. The
//! deadline is a guard, not a measurement: every case here finishes in a few
//! seconds; the deadline only stops a run that would never finish.

use std::io::Read;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

/// Address-space cap of the child: far above what a good run needs (about
/// 130 MB for the 30,000-file chain), far below the 24 GB `/dev/zero` took.
const MEMORY_CAP: u64 = 2 << 30;
/// A run still going after this long is taken as a hang.
const DEADLINE: Duration = Duration::from_secs(120);

/// How a bounded run ended.
#[derive(Debug)]
struct Outcome {
    /// Exit code; `None` when killed by a signal (stack overflow abort) or
    /// by the deadline.
    code: Option<i32>,
    timed_out: bool,
    stderr: String,
}

/// A fresh directory for one test, removed when dropped.
struct TempDir(PathBuf);

impl TempDir {
    fn new(test: &str) -> Self {
        let dir =
            std::env::temp_dir().join(format!("mavgen-rs-hostile-{}-{test}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).expect("cannot create temp dir");
        TempDir(dir)
    }

    fn write(&self, name: &str, text: &str) {
        std::fs::write(self.0.join(name), text).expect("cannot write fixture");
    }
}

impl Drop for TempDir {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

/// A dialect file with one message `M{id}` and the given includes.
fn dialect(id: usize, includes: &[&str]) -> String {
    let includes: String = includes
        .iter()
        .map(|i| format!("  <include>{i}</include>\n"))
        .collect();
    format!(
        "<?xml version=\"1.0\"?>\n<mavlink>\n{includes}  <messages>\n    <message id=\"{id}\" name=\"M{id}\">\n      <field type=\"uint8_t\" name=\"a\">a</field>\n    </message>\n  </messages>\n</mavlink>\n"
    )
}

/// Runs `mavgen-rs check ARGS` in `dir` under [`MEMORY_CAP`] and [`DEADLINE`].
fn check_bounded(dir: &Path, args: &[&str]) -> Outcome {
    let mut all = vec!["check"];
    all.extend_from_slice(args);
    mavgen_bounded(dir, &all)
}

/// Runs `mavgen-rs ARGS` in `dir` under [`MEMORY_CAP`] and [`DEADLINE`].
fn mavgen_bounded(dir: &Path, args: &[&str]) -> Outcome {
    let mut cmd = Command::new(env!("CARGO_BIN_EXE_mavgen-rs"));
    cmd.current_dir(dir)
        .args(args)
        .stdin(Stdio::null())
        .stdout(Stdio::null())
        .stderr(Stdio::piped());
    cap_memory(&mut cmd);
    let mut child = cmd.spawn().expect("cannot run mavgen-rs");
    // Drain stderr on a thread so a chatty child cannot block on a full pipe.
    let mut pipe = child.stderr.take().expect("stderr is piped");
    let reader = std::thread::spawn(move || {
        let mut s = String::new();
        let _ = pipe.read_to_string(&mut s);
        s
    });
    let start = Instant::now();
    let (status, timed_out) = loop {
        if let Some(status) = child.try_wait().expect("cannot wait for mavgen-rs") {
            break (Some(status), false);
        }
        if start.elapsed() > DEADLINE {
            let _ = child.kill();
            let _ = child.wait();
            break (None, true);
        }
        std::thread::sleep(Duration::from_millis(20));
    };
    Outcome {
        code: status.and_then(|s| s.code()),
        timed_out,
        stderr: reader.join().expect("stderr reader panicked"),
    }
}

#[cfg(unix)]
fn cap_memory(cmd: &mut Command) {
    use std::os::unix::process::CommandExt;
    // SAFETY: setrlimit is async-signal-safe and touches no memory of the
    // parent; nothing else runs between fork and exec.
    unsafe {
        cmd.pre_exec(|| {
            let lim = libc::rlimit {
                rlim_cur: MEMORY_CAP as libc::rlim_t,
                rlim_max: MEMORY_CAP as libc::rlim_t,
            };
            if libc::setrlimit(libc::RLIMIT_AS, &lim) != 0 {
                return Err(std::io::Error::last_os_error());
            }
            Ok(())
        });
    }
}

#[cfg(not(unix))]
fn cap_memory(_: &mut Command) {}

/// Asserts the run ended by itself with exit status 1 and `line` on stderr.
#[track_caller]
fn assert_error(o: &Outcome, line: &str) {
    assert!(!o.timed_out, "mavgen-rs hung (killed after {DEADLINE:?})");
    assert_eq!(o.code, Some(1), "stderr: {}", o.stderr);
    assert!(
        o.stderr.lines().any(|l| l == line),
        "stderr lacks {line:?}:\n{}",
        o.stderr
    );
}

#[cfg(unix)]
fn mkfifo(path: &Path) {
    use std::os::unix::ffi::OsStrExt;
    let c = std::ffi::CString::new(path.as_os_str().as_bytes()).unwrap();
    // SAFETY: a valid NUL-terminated path.
    let rc = unsafe { libc::mkfifo(c.as_ptr(), 0o600) };
    assert_eq!(rc, 0, "mkfifo: {}", std::io::Error::last_os_error());
}

#[cfg(unix)]
#[test]
fn an_include_of_dev_zero_is_an_error_at_the_include() {
    let t = TempDir::new("dev-zero");
    t.write("root.xml", &dialect(1, &["/dev/zero"]));
    let o = check_bounded(&t.0, &["root.xml"]);
    assert_error(
        &o,
        "root.xml:3:3: error: cannot read included file /dev/zero: it is a character device, not a regular file",
    );
}

#[cfg(unix)]
#[test]
fn an_include_of_a_fifo_is_an_error_at_the_include() {
    let t = TempDir::new("fifo-include");
    mkfifo(&t.0.join("pipe.xml"));
    t.write("root.xml", &dialect(1, &["pipe.xml"]));
    let o = check_bounded(&t.0, &["root.xml"]);
    assert_error(
        &o,
        "root.xml:3:3: error: cannot read included file pipe.xml: it is a FIFO, not a regular file",
    );
}

#[cfg(unix)]
#[test]
fn a_fifo_or_device_on_the_command_line_is_an_error() {
    let t = TempDir::new("fifo-root");
    mkfifo(&t.0.join("pipe.xml"));
    let o = check_bounded(&t.0, &["pipe.xml"]);
    assert_error(
        &o,
        "error: cannot read pipe.xml: it is a FIFO, not a regular file",
    );
    let o = check_bounded(&t.0, &["/dev/zero"]);
    assert_error(
        &o,
        "error: cannot read /dev/zero: it is a character device, not a regular file",
    );
}

#[test]
fn an_include_of_a_directory_is_an_error_at_the_include() {
    let t = TempDir::new("dir-include");
    std::fs::create_dir(t.0.join("sub.xml")).unwrap();
    t.write("root.xml", &dialect(1, &["sub.xml"]));
    let o = check_bounded(&t.0, &["root.xml"]);
    assert_error(
        &o,
        "root.xml:3:3: error: cannot read included file sub.xml: it is a directory, not a regular file",
    );
}

#[test]
fn an_include_above_8_mib_is_an_error_and_one_at_8_mib_is_read() {
    let t = TempDir::new("big-include");
    // A valid dialect padded with a comment to exactly the limit, then to
    // one byte more.
    let body = dialect(2, &[]);
    let pad = mavgen_rs::MAX_FILE_BYTES as usize - body.len() - "<!---->\n".len();
    let at_limit = format!("{body}<!--{}-->\n", "x".repeat(pad));
    assert_eq!(at_limit.len() as u64, mavgen_rs::MAX_FILE_BYTES);
    t.write("big.xml", &at_limit);
    t.write("root.xml", &dialect(1, &["big.xml"]));
    let o = check_bounded(&t.0, &["root.xml"]);
    assert_eq!(o.code, Some(0), "stderr: {}", o.stderr);

    t.write("big.xml", &format!("{at_limit} "));
    let o = check_bounded(&t.0, &["root.xml"]);
    assert_error(
        &o,
        "root.xml:3:3: error: cannot read included file big.xml: it is larger than 8388608 bytes (8 MiB), the most mavgen-rs reads from one file",
    );
}

#[test]
fn more_than_64_mib_over_all_files_is_an_error_at_the_include_crossing_it() {
    let t = TempDir::new("total");
    // Nine files of 7.5 MiB each: each under the per-file limit, 67.5 MiB
    // in all; the ninth crosses 64 MiB.
    let names: Vec<String> = (0..9).map(|i| format!("part{i}.xml")).collect();
    for (i, name) in names.iter().enumerate() {
        let body = dialect(10 + i, &[]);
        let pad = (15 << 19) - body.len() - "<!---->\n".len();
        t.write(name, &format!("{body}<!--{}-->\n", "x".repeat(pad)));
    }
    let refs: Vec<&str> = names.iter().map(String::as_str).collect();
    t.write("root.xml", &dialect(1, &refs));
    let o = check_bounded(&t.0, &["root.xml"]);
    assert_error(
        &o,
        "root.xml:11:3: error: cannot read included file part8.xml: the files read would exceed 67108864 bytes (64 MiB) in all, the most mavgen-rs reads in one run",
    );
}

/// Writes `c0.xml` … `c{n-1}.xml`, each including the next; the last
/// includes `last_includes` if given.
fn chain(t: &TempDir, n: usize, last_includes: Option<&str>) {
    for i in 0..n {
        let next = format!("c{}.xml", i + 1);
        let inc: Vec<&str> = if i + 1 < n {
            vec![next.as_str()]
        } else {
            last_includes.into_iter().collect()
        };
        t.write(&format!("c{i}.xml"), &dialect(i, &inc));
    }
}

#[test]
fn a_30000_deep_include_chain_is_checked() {
    let t = TempDir::new("chain");
    chain(&t, 30_000, None);
    let o = check_bounded(&t.0, &["c0.xml"]);
    assert!(!o.timed_out, "mavgen-rs hung");
    assert_eq!(o.code, Some(0), "stderr: {}", o.stderr);
    assert!(
        o.stderr
            .contains("ok: 30000 messages, 0 enums in 30000 files"),
        "stderr: {}",
        o.stderr
    );
}

#[test]
fn a_30000_file_include_cycle_is_one_short_error() {
    let t = TempDir::new("cycle");
    chain(&t, 30_000, Some("c0.xml"));
    let o = check_bounded(&t.0, &["c0.xml"]);
    assert!(!o.timed_out, "mavgen-rs hung");
    assert_eq!(o.code, Some(1), "stderr: {}", o.stderr);
    let errors: Vec<&str> = o.stderr.lines().filter(|l| l.contains("error:")).collect();
    assert_eq!(errors.len(), 1, "stderr: {}", o.stderr);
    assert!(
        // The include of the last file (its line 3) closes the cycle.
        errors[0] == (
            "c29999.xml:3:3: error: include cycle: c0.xml -> c1.xml -> c2.xml -> c3.xml -> (29992 more) -> c29996.xml -> c29997.xml -> c29998.xml -> c29999.xml -> c0.xml"
        ),
        "{}",
        errors[0]
    );
}

#[test]
fn a_million_nested_elements_are_read_in_linear_time() {
    let t = TempDir::new("nesting");
    let depth = 1_000_000;
    let body = dialect(1, &[]);
    let nested = format!("<x>{}{}</x>", "<a>".repeat(depth), "</a>".repeat(depth));
    t.write(
        "deep.xml",
        &body.replace("<messages>", &format!("{nested}<messages>")),
    );
    let o = check_bounded(&t.0, &["deep.xml"]);
    assert!(!o.timed_out, "mavgen-rs hung");
    assert_eq!(o.code, Some(0), "stderr: {}", o.stderr);
}

#[cfg(unix)]
#[test]
fn generate_replaces_an_output_path_that_is_a_fifo_without_reading_it() {
    let t = TempDir::new("out-fifo");
    t.write("root.xml", &dialect(1, &[]));
    std::fs::create_dir(t.0.join("out")).unwrap();
    // mod.rs is one of the outputs (compared before writing); stale.rs is
    // not (checked for the generated-file header before removal).
    mkfifo(&t.0.join("out/mod.rs"));
    mkfifo(&t.0.join("out/stale.rs"));
    let o = mavgen_bounded(&t.0, &["generate", "root.xml", "-o", "out"]);
    assert!(!o.timed_out, "mavgen-rs hung");
    assert_eq!(o.code, Some(0), "stderr: {}", o.stderr);
    assert!(t.0.join("out/mod.rs").metadata().unwrap().is_file());
    // Not ours (no header could be read): left alone.
    assert!(t.0.join("out/stale.rs").symlink_metadata().is_ok());
}

#[cfg(unix)]
#[test]
fn a_message_list_that_is_a_fifo_is_an_error() {
    let t = TempDir::new("list-fifo");
    t.write("root.xml", &dialect(1, &[]));
    mkfifo(&t.0.join("list.txt"));
    let o = mavgen_bounded(
        &t.0,
        &[
            "generate",
            "root.xml",
            "-o",
            "out",
            "--messages",
            "@list.txt",
        ],
    );
    assert_error(
        &o,
        "error: --messages @list.txt: it is a FIFO, not a regular file",
    );
}

/// The first message of [`dialect`] as an interrupted copy leaves it: cut
/// before `</messages>`, so `<messages>` and `<mavlink>` stay open.
fn truncated(id: usize) -> String {
    let whole = dialect(id, &[]);
    whole[..whole.find("  </messages>").expect("a dialect")].to_string()
}

#[test]
fn a_truncated_file_is_an_error_and_generates_nothing() {
    // Was generated as if whole. pymavlink refuses it too ("no element
    // found: line 7, column 0").
    let t = TempDir::new("truncated");
    t.write("cut.xml", &truncated(1));
    let expected = "cut.xml:7:1: error: the file ends inside <messages> (opened at 3:3)";
    assert_error(&check_bounded(&t.0, &["cut.xml"]), expected);
    let o = mavgen_bounded(&t.0, &["generate", "cut.xml", "-o", "out"]);
    assert_error(&o, expected);
    assert!(
        !t.0.join("out").exists(),
        "output written for a truncated file"
    );
}

#[test]
fn a_truncated_include_is_an_error_in_that_file() {
    // A half-written download of an included file (pymavlink: "no element
    // found: line 7, column 0", while parsing cut.xml).
    let t = TempDir::new("truncated-include");
    t.write("root.xml", &dialect(1, &["cut.xml"]));
    t.write("cut.xml", &truncated(2));
    assert_error(
        &check_bounded(&t.0, &["root.xml"]),
        "cut.xml:7:1: error: the file ends inside <messages> (opened at 3:3)",
    );
}

#[test]
fn every_truncation_of_a_real_dialect_is_refused() {
    // Cut minimal.xml (47 KB, the upstream file) at every 61st byte and at
    // every `>` (where a cut leaves well-formed tags and only the missing
    // end tags tell): each prefix short of `</mavlink>` must be refused with
    // an error that has a position. Only a cut in the trailing newline is
    // whole.
    let path = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../fbwag-dialect/message_definitions/minimal.xml");
    let text = std::fs::read_to_string(&path).expect("minimal.xml");
    let whole = text.rfind("</mavlink>").expect("a root end tag") + "</mavlink>".len();
    let cuts = (0..whole).step_by(61).chain(
        text.match_indices('>')
            .map(|(i, _)| i + 1)
            .filter(|&i| i < whole),
    );
    let mut count = 0;
    for cut in cuts.filter(|&c| text.is_char_boundary(c)) {
        match mavgen_rs::Schema::from_text("minimal.xml", &text[..cut]) {
            Ok(_) => panic!("accepted minimal.xml cut at byte {cut}"),
            Err(diags) => assert!(
                diags.iter().any(|d| d.position.is_some()),
                "cut at {cut}: no positioned error: {diags:?}"
            ),
        }
        count += 1;
    }
    assert!(count > 1000, "only {count} cuts tried");
    assert!(mavgen_rs::Schema::from_text("minimal.xml", &text[..whole]).is_ok());
}
