//! The `mavgen-rs` command line: exit status, where diagnostics go, what
//! `table` prints, and that `generate` writes all or nothing, deterministically.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::Command;

fn manifest_dir() -> &'static Path {
    Path::new(env!("CARGO_MANIFEST_DIR"))
}

fn fixtures_dir() -> PathBuf {
    manifest_dir().join("tests/fixtures")
}

/// The binary, run from `dir`.
fn mavgen_in(dir: &Path) -> Command {
    let mut cmd = Command::new(env!("CARGO_BIN_EXE_mavgen-rs"));
    cmd.current_dir(dir);
    cmd
}

/// Exit code, stdout and stderr of `cmd`.
fn run(cmd: &mut Command) -> (Option<i32>, String, String) {
    let out = cmd.output().expect("cannot run mavgen-rs");
    (
        out.status.code(),
        String::from_utf8(out.stdout).expect("stdout is not UTF-8"),
        String::from_utf8(out.stderr).expect("stderr is not UTF-8"),
    )
}

/// A fresh, empty directory for one test, removed when dropped.
struct TempDir(PathBuf);

impl TempDir {
    fn new(test: &str) -> Self {
        let dir = std::env::temp_dir().join(format!("mavgen-rs-cli-{}-{test}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).expect("cannot create temp dir");
        TempDir(dir)
    }
}

impl Drop for TempDir {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

/// Every file in `dir` (hidden ones too) by name, with its bytes.
fn contents(dir: &Path) -> BTreeMap<String, Vec<u8>> {
    std::fs::read_dir(dir)
        .unwrap_or_else(|e| panic!("cannot list {}: {e}", dir.display()))
        .map(|entry| {
            let entry = entry.unwrap();
            let name = entry.file_name().to_string_lossy().into_owned();
            (name, std::fs::read(entry.path()).unwrap())
        })
        .collect()
}

#[test]
fn check_broken_fixture_exits_1_with_file_line_col() {
    let (code, stdout, stderr) =
        run(mavgen_in(&fixtures_dir()).args(["check", "unknown_type.xml"]));
    assert_eq!(code, Some(1), "stderr: {stderr}");
    assert_eq!(stdout, "");
    assert!(
        stderr.contains("unknown_type.xml:6:14: error: field bad: unknown type `float_t`"),
        "stderr: {stderr}"
    );
}

#[test]
fn check_reports_errors_in_included_files_with_their_path() {
    let (code, _, stderr) = run(mavgen_in(&fixtures_dir()).args(["check", "dup_id_root.xml"]));
    assert_eq!(code, Some(1), "stderr: {stderr}");
    assert!(
        stderr.contains("dup_id_included.xml:7:31: error: duplicate message id 5"),
        "stderr: {stderr}"
    );
}

#[test]
fn check_prints_warnings_and_exits_0() {
    let (code, _, stderr) =
        run(mavgen_in(&fixtures_dir()).args(["check", "system_id_warning.xml"]));
    assert_eq!(code, Some(0), "stderr: {stderr}");
    assert!(
        stderr.contains("system_id_warning.xml:6:7: warning: field NOTICE.system_id"),
        "stderr: {stderr}"
    );
    assert!(!stderr.contains("error:"), "stderr: {stderr}");
}

/// Whether `line` matches `^\d+ [A-Z0-9_]+ \d+ \d+ \d+$`.
fn is_table_row(line: &str) -> bool {
    let parts: Vec<&str> = line.split(' ').collect();
    let number = |s: &str| !s.is_empty() && s.bytes().all(|b| b.is_ascii_digit());
    parts.len() == 5
        && number(parts[0])
        && !parts[1].is_empty()
        && parts[1]
            .bytes()
            .all(|b| b.is_ascii_uppercase() || b.is_ascii_digit() || b == b'_')
        && parts[2..].iter().all(|s| number(s))
}

#[test]
fn table_prints_only_rows_sorted_by_id() {
    let (code, stdout, stderr) =
        run(mavgen_in(manifest_dir()).args(["table", "../message_definitions/fbwag.xml"]));
    assert_eq!(code, Some(0), "stderr: {stderr}");
    assert!(stdout.ends_with('\n'), "stdout does not end with a newline");
    let lines: Vec<&str> = stdout.lines().collect();
    assert!(lines.len() > 100, "only {} rows", lines.len());
    for line in &lines {
        assert!(is_table_row(line), "not a table row: {line:?}");
    }
    let ids: Vec<u32> = lines
        .iter()
        .map(|l| l.split(' ').next().unwrap().parse().unwrap())
        .collect();
    assert!(
        ids.windows(2).all(|w| w[0] < w[1]),
        "rows are not sorted by id (or an id repeats)"
    );
    assert_eq!(lines[0], "0 HEARTBEAT 50 9 9");
    assert!(lines.contains(&"15001 FBWAG_NOTICE 30 12 12"));
}

#[test]
fn generate_broken_fixture_writes_nothing() {
    let tmp = TempDir::new("generate_broken_fixture_writes_nothing");
    let existing = tmp.0.join("existing");
    let missing = tmp.0.join("missing");
    std::fs::create_dir(&existing).unwrap();
    let broken = fixtures_dir().join("unknown_type.xml");
    for out in [&existing, &missing] {
        let (code, _, stderr) = run(mavgen_in(&tmp.0)
            .arg("generate")
            .arg(&broken)
            .arg("-o")
            .arg(out));
        assert_eq!(code, Some(1), "stderr: {stderr}");
        assert!(
            stderr.contains(&format!("{}:6:14: error:", broken.display())),
            "stderr: {stderr}"
        );
    }
    assert_eq!(contents(&existing), BTreeMap::new());
    assert!(!missing.exists(), "generate created its output directory");
}

#[test]
fn generate_is_deterministic() {
    let tmp = TempDir::new("generate_is_deterministic");
    let xml = fixtures_dir().join("valid_root.xml");
    // Two separate runs (separate processes, separate directories, the same
    // relative `-o`, so the regenerate hint in the headers is the same).
    let mut outputs = Vec::new();
    for run_dir in ["run1", "run2"] {
        let dir = tmp.0.join(run_dir);
        std::fs::create_dir(&dir).unwrap();
        let (code, stdout, stderr) = run(mavgen_in(&dir)
            .arg("generate")
            .arg(&xml)
            .args(["-o", "out"]));
        assert_eq!(code, Some(0), "stderr: {stderr}");
        assert_eq!(stdout, "");
        outputs.push(contents(&dir.join("out")));
    }
    let names: Vec<&str> = outputs[0].keys().map(String::as_str).collect();
    assert_eq!(names, ["mod.rs", "valid_included.rs", "valid_root.rs"]);
    assert!(outputs[0]["mod.rs"].starts_with(b"// @generated by mavgen-rs"));
    assert!(
        outputs[0] == outputs[1],
        "the two runs produced different files"
    );

    // A rerun into the same directory leaves it exactly as it was.
    let dir = tmp.0.join("run1");
    let (code, _, stderr) = run(mavgen_in(&dir)
        .arg("generate")
        .arg(&xml)
        .args(["-o", "out"]));
    assert_eq!(code, Some(0), "stderr: {stderr}");
    assert!(
        contents(&dir.join("out")) == outputs[0],
        "rerun changed the output"
    );
}

#[test]
fn help_mentions_every_subcommand() {
    let (code, stdout, stderr) = run(mavgen_in(manifest_dir()).arg("--help"));
    assert_eq!(code, Some(0), "stderr: {stderr}");
    for sub in ["generate", "check", "table"] {
        assert!(stdout.contains(sub), "--help lacks `{sub}`:\n{stdout}");
    }
}

#[test]
fn generate_reads_message_names_from_a_file() {
    let tmp = TempDir::new("generate_reads_message_names_from_a_file");
    let xml = fixtures_dir().join("valid_root.xml");
    std::fs::write(
        tmp.0.join("subset.txt"),
        "# what the test keeps\nSMALL_PING  # trailing comment\n\nHEARTBEAT,\n",
    )
    .unwrap();
    let (code, _, stderr) = run(mavgen_in(&tmp.0).arg("generate").arg(&xml).args([
        "-o",
        "from-file",
        "--messages",
        "@subset.txt",
    ]));
    assert_eq!(code, Some(0), "stderr: {stderr}");
    assert!(stderr.contains("(2 messages"), "stderr: {stderr}");
    let (code, _, stderr) = run(mavgen_in(&tmp.0).arg("generate").arg(&xml).args([
        "-o",
        "inline",
        "--messages",
        "SMALL_PING,HEARTBEAT",
    ]));
    assert_eq!(code, Some(0), "stderr: {stderr}");
    let strip_hint = |files: BTreeMap<String, Vec<u8>>| -> BTreeMap<String, String> {
        files
            .into_iter()
            .map(|(n, b)| {
                let text = String::from_utf8(b).unwrap();
                let text: String = text
                    .lines()
                    .filter(|l| !l.starts_with("// Regenerate"))
                    .collect::<Vec<_>>()
                    .join("\n");
                (n, text)
            })
            .collect()
    };
    assert_eq!(
        strip_hint(contents(&tmp.0.join("from-file"))),
        strip_hint(contents(&tmp.0.join("inline")))
    );

    // A missing or empty file is an error, and nothing is written.
    std::fs::write(tmp.0.join("empty.txt"), "# nothing\n").unwrap();
    for (arg, says) in [
        ("@missing.txt", "missing.txt"),
        ("@empty.txt", "names no message"),
    ] {
        let (code, _, stderr) = run(mavgen_in(&tmp.0).arg("generate").arg(&xml).args([
            "-o",
            "never",
            "--messages",
            arg,
        ]));
        assert_eq!(code, Some(1), "{arg}: stderr: {stderr}");
        assert!(stderr.contains(says), "{arg}: stderr: {stderr}");
        assert!(!tmp.0.join("never").exists());
    }
}
