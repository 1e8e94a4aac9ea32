//! `--config PATH`: `fbwag router` and `fbwag cc` take their options from
//! a TOML file (deploy/router.toml and deploy/cc.toml are the examples),
//! or from a directory's `*.toml` files in name order; a later file's
//! options and the command line's win; a bad file or value is refused
//! with the file's line and column, exit status 2.

use fbwag_dialect::dialects::minimal::Heartbeat;
use fbwag_dialect::{encode, Header, Version};
use std::net::UdpSocket;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};
use std::time::{Duration, Instant};

mod common;

use common::{free_port, repo};

fn fbwag() -> Command {
    Command::new(env!("CARGO_BIN_EXE_fbwag"))
}

/// A fresh directory for one test's files.
fn dir(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("fbwag-config-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

fn write(dir: &Path, name: &str, text: &str) -> PathBuf {
    let p = dir.join(name);
    std::fs::write(&p, text).unwrap();
    p
}

fn stderr(out: &Output) -> String {
    String::from_utf8_lossy(&out.stderr).into_owned()
}

fn heartbeat() -> Vec<u8> {
    let mut buf = [0u8; 280];
    let h = Header {
        seq: 0,
        sysid: 1,
        compid: 1,
    };
    let n = encode(Version::V2, h, &Heartbeat::default(), None, &mut buf).unwrap();
    buf[..n].to_vec()
}

/// The router's links from the file: what arrives on one leaves on the
/// other; and `--duration` on the command line ends it before the file's.
#[test]
fn the_router_routes_between_the_links_of_its_file() {
    let d = dir("routes");
    let (a, b) = (free_port(), free_port());
    let sink = UdpSocket::bind(("127.0.0.1", b)).unwrap();
    sink.set_read_timeout(Some(Duration::from_secs(5))).unwrap();
    let file = write(
        &d,
        "router.toml",
        &format!(
            "# two links\nlinks = [\"udpin:127.0.0.1:{a}\", \"udpout:127.0.0.1:{b}\"]\n\
             duration = 600\nreport = 0.5\nsniffer = [2]\n"
        ),
    );
    let started = Instant::now();
    let mut router = fbwag();
    router.args(["router", "--config"]).arg(&file);
    router.args(["--duration", "2"]);
    routes_a_heartbeat(router, a, &sink);
    assert!(
        started.elapsed() < Duration::from_secs(30),
        "--duration 2 on the command line wins over the file's 600"
    );
}

/// Runs `router` and sends a heartbeat to its port `a` until `sink`
/// receives it; the router must then exit cleanly by itself.
fn routes_a_heartbeat(mut router: Command, a: u16, sink: &UdpSocket) {
    let child = router.stderr(std::process::Stdio::piped()).spawn().unwrap();
    let source = UdpSocket::bind("127.0.0.1:0").unwrap();
    let hb = heartbeat();
    let mut buf = [0u8; 300];
    let got = (0..20).find_map(|_| {
        source.send_to(&hb, ("127.0.0.1", a)).unwrap();
        sink.set_read_timeout(Some(Duration::from_millis(200)))
            .unwrap();
        sink.recv(&mut buf).ok()
    });
    let out = child.wait_with_output().unwrap();
    // Heartbeats queued together in the router leave in one datagram.
    let got = got.map(|n| &buf[..n]);
    let copies = got.map_or(1, |g| (g.len() / hb.len()).max(1));
    assert_eq!(got, Some(&hb.repeat(copies)[..]), "{}", stderr(&out));
    assert!(out.status.success(), "{}", stderr(&out));
}

/// A directory as mavlink-router's config.d: its *.toml files in name
/// order, each adding links, a later one's single values winning; other
/// entries there (backups, hidden files, a directory) left alone; a bad
/// file named by its own path and line.
#[test]
fn a_directory_adds_up_its_files_in_name_order() {
    let d = dir("conf-d");
    let (a, b) = (free_port(), free_port());
    let sink = UdpSocket::bind(("127.0.0.1", b)).unwrap();
    write(
        &d,
        "10-fc.toml",
        &format!("links = [\"udpin:127.0.0.1:{a}\"]\nduration = 600\n"),
    );
    write(
        &d,
        "20-ground.toml",
        &format!("links = [\"udpout:127.0.0.1:{b}\"]\nduration = 2\n"),
    );
    write(&d, "20-ground.toml~", "this is no TOML [");
    write(&d, "README", "this is no TOML [");
    std::fs::create_dir(d.join("15-not-a-file.toml")).unwrap();
    write(&d, ".hidden.toml", "this is no TOML [");
    let started = Instant::now();
    let mut router = fbwag();
    router.args(["router", "--config"]).arg(&d);
    routes_a_heartbeat(router, a, &sink);
    assert!(
        started.elapsed() < Duration::from_secs(30),
        "20-ground.toml's duration 2 wins over 10-fc.toml's 600"
    );

    // The command line's links add to the files'.
    let extra = free_port();
    let out = fbwag()
        .args(["router", "--config"])
        .arg(&d)
        .arg(format!("udpin:127.0.0.1:{extra}"))
        .args(["--duration", "0.3"])
        .output()
        .unwrap();
    let log = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success(), "{}", stderr(&out));
    assert_eq!(log.matches(": udpin:127.0.0.1:").count(), 2, "{log}");
    assert!(
        log.contains(&format!("link 3: udpin:127.0.0.1:{extra}")),
        "{log}"
    );
    let out = fbwag()
        .args(["router", "udpin:127.0.0.1:1"])
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(2));
    assert!(
        stderr(&out).contains("two links or more"),
        "{}",
        stderr(&out)
    );

    let bad = write(&d, "30-bad.toml", "report = 1\nrequire_signed = 1\n");
    let out = fbwag()
        .args(["router", "--config"])
        .arg(&d)
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(2), "{}", stderr(&out));
    let at = format!("{}:2:18:", bad.display());
    assert!(stderr(&out).contains(&at), "wants {at}: {}", stderr(&out));
    let out = fbwag()
        .args(["router", "--config"])
        .arg(d.join("absent.d"))
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(2), "{}", stderr(&out));
}

/// The command line's value for a link replaces a file's (a pinned peer
/// moved without editing the file), and a value refused because of what
/// the command line added is blamed on the command line, not the file.
#[test]
fn the_command_line_overrides_a_files_value_for_a_link() {
    let d = dir("override");
    let file = write(
        &d,
        "router.toml",
        "links = [\"udpin:127.0.0.1:1\", \"udpout:127.0.0.1:2\"]\n\
         peer = [\"1:127.0.0.1:9\"]\n\
         filter_in = [\"1:block-msg=1,2,3,4,5,6,7,8,9\"]\n",
    );
    let out = fbwag()
        .args(["router", "--duration", "0.2", "--config"])
        .arg(&file)
        .args(["--peer", "1:127.0.0.1:7"])
        .output()
        .unwrap();
    let log = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success(), "{}", stderr(&out));
    assert!(log.contains("answers 127.0.0.1:7 only"), "{log}");
    let out = fbwag()
        .args(["router", "--config"])
        .arg(&file)
        .args(["--filter-in", "1:block-msg=10,11,12,13,14,15,16,17"])
        .output()
        .unwrap();
    let err = stderr(&out);
    assert_eq!(out.status.code(), Some(2), "{err}");
    assert!(err.contains("--filter-in 1:block-msg=10,"), "{err}");
    assert!(
        !err.contains("router.toml"),
        "the file is not at fault: {err}"
    );
}

/// What a bad file says, and where.
#[test]
fn a_bad_file_is_refused_with_its_line_and_column() {
    let d = dir("bad");
    let cases: &[(&str, &str, &str)] = &[
        (
            "links = [\"udpin:127.0.0.1:1\", \"udpout:127.0.0.1:2\"]\nsign_kye = \"x\"\n",
            ":2:1:",
            "no such option",
        ),
        (
            "links = [\"udpin:127.0.0.1:1\", \"udpout:127.0.0.1:2\"]\nreport = -3\n",
            ":2:10:",
            "`report`",
        ),
        (
            "links = [\"udpin:127.0.0.1:1\", \"udpout:127.0.0.1:2\"]\nrequire_signed = 1\n",
            ":2:18:",
            "true or false",
        ),
        (
            "links = [\"udpin:127.0.0.1:1\", \"bogus:1\"]\n",
            ":1:31:",
            "`links`",
        ),
        (
            "links = [\"udpin:127.0.0.1:1\", \"udpout:127.0.0.1:2\"]\nsniffer = [1, 0]\n",
            ":2:15:",
            "`sniffer`",
        ),
        (
            "links = [\"udpin:127.0.0.1:1\", \"udpout:127.0.0.1:2\"]\nfilter_in = [\"9:allow-msg=0\"]\n",
            ":2:14:",
            "`filter_in`: 9:allow-msg=0: link 9: there are 2 links",
        ),
        (
            "links = [\"udpin:127.0.0.1:1\", \"udpout:127.0.0.1:2\"]\nsniffer = [5]\n",
            ":2:12:",
            "`sniffer`: 5: link 5: there are 2 links",
        ),
        (
            "links = [\"udpin:127.0.0.1:1\", \"udpout:127.0.0.1:2\"]\npeer = [\"2:127.0.0.1:5\"]\n",
            ":2:9:",
            "`peer`: 2: link udpout:127.0.0.1:2 does not listen",
        ),
        // An array over several lines: the element's own line.
        (
            "links = [\n  \"udpin:127.0.0.1:1\",\n  \"udpout:127.0.0.1:2\",\n]\nfilter_out = [\n  \"1:block-msg=0\",\n  \"3:block-msg=0\",\n]\n",
            ":7:3:",
            "`filter_out`: 3:block-msg=0: link 3: there are 2 links",
        ),
        ("links = [\"udpin:127.0.0.1:1\",\n", ":1:", "unclosed array"),
        ("[router]\nlinks = []\n", ":1:2:", "no such option"),
    ];
    for (i, (text, place, what)) in cases.iter().enumerate() {
        let file = write(&d, &format!("bad{i}.toml"), text);
        let out = fbwag()
            .args(["router", "--config"])
            .arg(&file)
            .output()
            .unwrap();
        let err = stderr(&out);
        assert_eq!(out.status.code(), Some(2), "{text}: {err}");
        let at = format!("{}{place}", file.display());
        assert!(
            err.contains(&at) && err.contains(what),
            "{text}: wants {at} and {what}: {err}"
        );
    }
    let out = fbwag()
        .args(["router", "--config"])
        .arg(d.join("missing.toml"))
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(2));
    assert!(stderr(&out).contains("missing.toml"), "{}", stderr(&out));
}

/// The examples in deploy/ hold only options the programs take, with
/// values they accept: each runs, its devices and paths replaced by the
/// test's own.
#[test]
fn the_example_files_run() {
    let d = dir("examples");
    let key = write(&d, "key", &"ab".repeat(32));
    // A key file only its owner reads (a readable one is refused).
    use std::os::unix::fs::PermissionsExt;
    std::fs::set_permissions(&key, std::fs::Permissions::from_mode(0o600)).unwrap();
    for (program, example) in [("router", "deploy/router.toml"), ("cc", "deploy/cc.toml")] {
        let text = std::fs::read_to_string(repo().join(example)).unwrap();
        let mut text = text
            .replace("/etc/fbwag/key", &key.display().to_string())
            .replace("/var/lib/fbwag", &d.display().to_string())
            .replace("/var/log/fbwag", &d.display().to_string())
            .replace(
                "serial:/dev/ttyAMA0:921600",
                &format!("udpout:127.0.0.1:{}", free_port()),
            )
            .replace("0.0.0.0", "127.0.0.1")
            .replace("192.168.1.10", "127.0.0.1");
        for port in ["14550", "14540"] {
            text = text.replace(port, &free_port().to_string());
        }
        let file = write(&d, &format!("{program}.toml"), &text);
        let out = fbwag()
            .arg(program)
            .arg("--config")
            .arg(&file)
            .args(["--duration", "0.5"])
            .output()
            .unwrap();
        // No FC on the other end: the companion says so, with status 1.
        let unheard = program == "cc"
            && out.status.code() == Some(1)
            && String::from_utf8_lossy(&out.stdout).contains("was never heard");
        assert!(
            out.status.success() || unheard,
            "{example}: {}",
            stderr(&out)
        );
    }
}

/// The systemd units start the programs with the example's options, and
/// systemd finds nothing wrong in them (when `systemd-analyze` is here).
#[test]
fn the_systemd_units_run_the_programs_from_their_files() {
    let d = dir("units");
    for program in ["router", "cc"] {
        let unit = repo().join(format!("deploy/systemd/fbwag-{program}.service"));
        let text = std::fs::read_to_string(&unit).unwrap();
        let exec =
            format!("ExecStart=/usr/local/bin/fbwag {program} --config /etc/fbwag/{program}.toml");
        assert!(
            text.lines().any(|l| l == exec),
            "{}: no `{exec}`",
            unit.display()
        );
        assert!(repo().join(format!("deploy/{program}.toml")).exists());
        let local = write(
            &d,
            &format!("fbwag-{program}.service"),
            &text.replace("/usr/local/bin/fbwag", env!("CARGO_BIN_EXE_fbwag")),
        );
        let Ok(out) = Command::new("systemd-analyze")
            .args(["verify", "--man=no"])
            .arg(&local)
            .output()
        else {
            continue;
        };
        let said = format!("{}{}", String::from_utf8_lossy(&out.stdout), stderr(&out));
        assert!(
            out.status.success() && said.trim().is_empty(),
            "{}: {said}",
            unit.display()
        );
    }
}

/// Every key mavlink-router's examples/config.sample documents, in the
/// case it writes them or not (keys, kinds and values are read without
/// regard to case), every section kind and UDP mode.
const EVERY_KEY: &str = "# a main.conf\n\
[General]\nTcpServerPort = 5761\nReportStats = true\nDebugLogLevel = debug\n\
DeduplicationPeriod = 100\nSnifferSysid = 254\nMavlinkDialect = ardupilotmega\n\
Log = /var/log/flight-stack\nLogMode = while-armed\nLogSystemId = 1\n\
MinFreeSpace = 1048576\nMaxLogFiles = 10\nLogTelemetry = 1\n\
\n[UartEndpoint fc]\nDevice = /dev/ttyAMA0\nBaud = 921600\nFlowControl = true\n\
AllowMsgIdOut = 0,1,76\nBlockMsgIdOut = 30\nAllowSrcCompOut = 1,190\nBlockSrcCompOut = 200\n\
AllowSrcSysOut = 1,255\nBlockSrcSysOut = 7\nAllowMsgIdIn = 0,30,33\nBlockMsgIdIn = 24\n\
AllowSrcCompIn = 1\nBlockSrcCompIn = 154\nAllowSrcSysIn = 1\nBlockSrcSysIn = 9\n\
\n[udpendpoint gcs]\nmode = normal\naddress = 10.0.0.2\nfilter = 0,30\n\
\n[UdpEndpoint radio]\nMode = Normal\nAddress = 192.168.1.255\nPort = 14551\n\
; a server\n[UdpEndpoint listen]\nMode = Server\nAddress = 0.0.0.0\nPort = 14560\n\
[UdpEndpoint legacy]\nMode = Eavesdropping\nAddress = [::1]\nPort = 14561\n\
[TcpEndpoint mavproxy]\nAddress = 127.0.0.1\nPort = 5762\nRetryTimeout = 5\nBlockMsgIdOut = 76";

/// What [`EVERY_KEY`] stands for.
const EVERY_KEY_TOML: &str = r#"dedup = 100
filter_in = [
    "fc:allow-msg=0,30,33",
    "fc:block-msg=24",
    "fc:allow-comp=1",
    "fc:block-comp=154",
    "fc:allow-sys=1",
    "fc:block-sys=9",
]
filter_out = [
    "fc:allow-msg=0,1,76",
    "fc:block-msg=30",
    "fc:allow-comp=1,190",
    "fc:block-comp=200",
    "fc:allow-sys=1,255",
    "fc:block-sys=7",
    "gcs:allow-msg=0,30",
    "mavproxy:block-msg=76",
]
flight_log = "/var/log/flight-stack"
flow_control = ["fc"]
links = [
    "fc=serial:/dev/ttyAMA0:921600",
    "gcs=udpout:10.0.0.2:14550",
    "radio=udpbcast:192.168.1.255:14551",
    "listen=udpin:0.0.0.0:14560",
    "legacy=udpin:[::1]:14561",
    "mavproxy=tcp:127.0.0.1:5762",
    "tcpin:0.0.0.0:5761",
]
log_level = "debug"
log_max_files = 10
log_mode = "while-armed"
log_sysid = 1
report = 10
sniffer_sysid = 254
tlog = "/var/log/flight-stack"
tlog_min_free = 1048576
"#;

/// `--print-config` of `args`: its output without the first line (the
/// files named), and its exit status.
fn printed(args: &[&std::ffi::OsStr]) -> (String, Option<i32>, String) {
    let out = fbwag().args(args).arg("--print-config").output().unwrap();
    let text = String::from_utf8_lossy(&out.stdout);
    let body = text.split_once('\n').map_or("", |(_, b)| b).to_string();
    (body, out.status.code(), stderr(&out))
}

/// A mavlink-router file read as it is: every key becomes its option
/// (endpoints named links, per-endpoint keys their options), checked as a
/// run checks them; the TOML printed stands for the same options.
#[test]
fn a_mavlink_router_file_is_read_as_it_is_and_printed_as_toml() {
    let d = dir("mlr-every");
    let conf = write(&d, "main.conf", EVERY_KEY);
    let (toml, code, err) = printed(&["router".as_ref(), "--config".as_ref(), conf.as_ref()]);
    assert_eq!(code, Some(0), "{err}");
    assert_eq!(toml, EVERY_KEY_TOML, "{err}");
    let again = write(&d, "printed.toml", &toml);
    let (toml, code, err) = printed(&["router".as_ref(), "--config".as_ref(), again.as_ref()]);
    assert_eq!((code, toml.as_str()), (Some(0), EVERY_KEY_TOML), "{err}");
    // Without a `.conf` name: told by its first section.
    let named = write(&d, "main", EVERY_KEY);
    let (toml, code, _) = printed(&["router".as_ref(), "--config".as_ref(), named.as_ref()]);
    assert_eq!((code, toml.as_str()), (Some(0), EVERY_KEY_TOML));
    // The companion takes the endpoints as --out links; the keys it has
    // no option for are refused at their line.
    let cc = ["cc", "--link", "udpin:127.0.0.1:14550", "--config"].map(std::ffi::OsStr::new);
    let (_, code, err) = printed(&[&cc[..], &[conf.as_os_str()]].concat());
    assert_eq!(code, Some(2));
    assert!(
        err.contains(&format!(
            "{}:7:1: `SnifferSysid`: no equivalent in fbwag cc",
            conf.display()
        )),
        "{err}"
    );
    let ground = write(
        &d,
        "cc.conf",
        "[General]\nLog = /var/log/fbwag\nLogTelemetry = true\nLogMode = while-armed\n\
         [UdpEndpoint gcs]\nMode = Server\nAddress = 0.0.0.0\nPort = 14550\nBlockMsgIdIn = 76\n",
    );
    let (_, code, err) = printed(&[&cc[..], &[ground.as_os_str()]].concat());
    assert_eq!(code, Some(2));
    assert!(
        err.contains("cc.conf:2:1: `Log`: no equivalent in fbwag cc"),
        "{err}"
    );
    let ground = write(
        &d,
        "cc.conf",
        "[General]\nMaxLogFiles = 3\n[UdpEndpoint gcs]\nMode = Server\nAddress = 0.0.0.0\n\
         Port = 14550\nBlockMsgIdIn = 76\n",
    );
    let (toml, code, err) = printed(&[&cc[..], &[ground.as_os_str()]].concat());
    assert_eq!(code, Some(2), "MaxLogFiles without Log: {toml}");
    assert!(
        err.contains("cc.conf:2:1: `MaxLogFiles`: applies to the logs of `Log`"),
        "{err}"
    );
    write(
        &d,
        "cc.conf",
        "[UdpEndpoint gcs]\nMode = Server\nAddress = 0.0.0.0\nPort = 14550\nBlockMsgIdIn = 76\n",
    );
    let (toml, code, err) = printed(&[&cc[..], &[ground.as_os_str()]].concat());
    assert_eq!(code, Some(0), "{err}");
    assert_eq!(
        toml,
        "filter_in = [\"gcs:block-msg=76\"]\nout = [\"gcs=udpin:0.0.0.0:14550\"]\n"
    );
}

/// mavlink-router's main.conf and config.d make one configuration: a
/// section met again in a later file takes its keys (a later value wins),
/// as mavlink-router merges them; a directory mixing its files with
/// fbwag's TOML ones is refused.
#[test]
fn main_conf_and_config_d_merge_as_mavlink_router_merges_them() {
    let d = dir("mlr-merge");
    let main = write(
        &d,
        "main.conf",
        "[UdpEndpoint gcs]\nMode = Normal\nAddress = 127.0.0.1\nPort = 14550\n\
         [UartEndpoint fc]\nDevice = /dev/ttyS1\n",
    );
    let conf_d = d.join("config.d");
    std::fs::create_dir_all(&conf_d).unwrap();
    write(&conf_d, "20-port.conf", "[udpendpoint GCS]\nport = 14555\n");
    write(
        &conf_d,
        "10-radio.conf",
        "[UartEndpoint fc]\nBaud = 57600\n",
    );
    write(&conf_d, "notes.txt", "[Ignored]\n");
    let (toml, code, err) = printed(&[
        "router".as_ref(),
        "--config".as_ref(),
        main.as_ref(),
        "--config".as_ref(),
        conf_d.as_ref(),
    ]);
    assert_eq!(code, Some(0), "{err}");
    assert_eq!(
        toml,
        "links = [\n    \"gcs=udpout:127.0.0.1:14555\",\n    \"fc=serial:/dev/ttyS1:57600\",\n]\n"
    );
    write(&conf_d, "30-more.toml", "dedup = 5\n");
    let (_, code, err) = printed(&[
        "router".as_ref(),
        "--config".as_ref(),
        main.as_ref(),
        "--config".as_ref(),
        conf_d.as_ref(),
    ]);
    assert_eq!(code, Some(2));
    assert!(err.contains("holds both *.conf"), "{err}");
}

/// A malformed mavlink-router file, or a key fbwag has no equivalent
/// for, is refused at its file, line and column, with the reason; never a
/// panic.
#[test]
fn a_bad_mavlink_router_file_is_refused_at_its_line() {
    let d = dir("mlr-bad");
    let udp = "[UdpEndpoint a]\nMode = Server\nAddress = 0.0.0.0\nPort = 14550\n";
    let cases: Vec<(String, &str, &str)> = vec![
        ("Port = 1\n".into(), ":1:1:", "a key before any section"),
        ("[General]\nTcpServerPort\n".into(), ":2:1:", "no `=`"),
        (
            "[Endpoint x]\n".into(),
            ":1:2:",
            "unknown section `Endpoint`",
        ),
        ("[UdpEndpoint]\n".into(), ":1:1:", "needs a name"),
        (
            "[General] # note\n".into(),
            ":1:10:",
            "after the section header",
        ),
        (
            format!("{udp}Port = 14550 # comment\n"),
            ":5:8:",
            "`Port`: expected a number",
        ),
        (
            format!("{udp}Group = radios\n"),
            ":5:1:",
            "`Group`: no equivalent",
        ),
        (
            format!("{udp}Baud = 57600\n"),
            ":5:1:",
            "not a key of [UdpEndpoint NAME]",
        ),
        (
            format!("{udp}[TcpEndpoint a]\nAddress=1.2.3.4\nPort=5\n"),
            ":5:1:",
            "named `a` too",
        ),
        (
            format!("{udp}[General]\nMavlinkDialect = px4\n"),
            ":6:18:",
            "one of auto",
        ),
        (
            format!("{udp}[General]\nDeduplicationPeriod = 70000\n"),
            ":6:23:",
            "from 0 to 60000",
        ),
        (
            format!("{udp}[General]\nSnifferSysid = 300\n"),
            ":6:16:",
            "from 0 to 255",
        ),
        (
            format!("{udp}AllowMsgIdIn = 1,2,3,4,5,6,7,8,9,10,11,12,13,14,15,16,17\n"),
            ":5:16:",
            "16",
        ),
        (
            "[UartEndpoint fc]\nDevice = /dev/ttyS0\nBaud = 57600,115200\n".into(),
            ":3:8:",
            "one rate",
        ),
        (
            "[UartEndpoint fc]\nBaud = 57600\n".into(),
            ":1:1:",
            "`Device` is required",
        ),
        (
            "[TcpEndpoint t]\nAddress = 127.0.0.1\nPort = 1\nRetryTimeout = 0\n".into(),
            ":4:16:",
            "every second",
        ),
        (
            "[UdpEndpoint x.y]\nMode=Server\nAddress=0.0.0.0\nPort=1\n".into(),
            ":1:1:",
            "cannot name a link",
        ),
        (
            "[UdpEndpoint b]\nMode = server\nAddress = 0.0.0.0\nPort = 0\n".into(),
            ":4:8:",
            "from 1 to 65535",
        ),
        ("[General]\n\u{e9}t\u{e9}\n".into(), ":2:1:", "no `=`"),
    ];
    for (i, (text, place, what)) in cases.iter().enumerate() {
        let file = write(&d, &format!("bad{i}.conf"), text);
        let out = fbwag()
            .args([
                "router",
                "udpin:127.0.0.1:1",
                "udpin:127.0.0.1:2",
                "--print-config",
                "--config",
            ])
            .arg(&file)
            .output()
            .unwrap();
        let err = stderr(&out);
        assert_eq!(out.status.code(), Some(2), "{text}: {err}");
        let at = format!("{}{place}", file.display());
        assert!(
            err.contains(&at) && err.contains(what),
            "{text}: wants {at} and {what}: {err}"
        );
    }
    // A byte that is not UTF-8, at its place.
    let file = d.join("latin1.conf");
    std::fs::write(&file, b"[General]\nLog = /var/log/caf\xe9\n").unwrap();
    let out = fbwag()
        .args(["router", "--config"])
        .arg(&file)
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(2));
    let err = stderr(&out);
    assert!(
        err.contains(&format!("{}:2:19: byte 0xe9 is not UTF-8", file.display())),
        "{err}"
    );
}

/// docs/deployment.md's migration example is deploy/mavlink-router/main.conf
/// as it is, and the TOML it shows is what `--print-config` prints of it.
#[test]
fn the_migration_example_is_in_the_deployment_page_as_printed() {
    let name = "deploy/mavlink-router/main.conf";
    let conf = std::fs::read_to_string(repo().join(name)).unwrap();
    let page = std::fs::read_to_string(repo().join("docs/deployment.md")).unwrap();
    let block = format!("<!-- {name} -->\n```ini\n{conf}```\n");
    assert!(
        page.contains(&block),
        "docs/deployment.md lacks {name} as it is"
    );
    let out = fbwag()
        .current_dir(repo())
        .args(["router", "--config", name, "--print-config"])
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", stderr(&out));
    let printed = String::from_utf8_lossy(&out.stdout);
    let block =
        format!("<!-- fbwag router --config {name} --print-config -->\n```toml\n{printed}```\n");
    assert!(
        page.contains(&block),
        "docs/deployment.md lacks what is printed:\n{printed}"
    );
}
