//! A ground tool that cannot sign, through `fbwag cc --trusted-out`, against
//! an FC that requires signatures: MAVSDK (mavsdk_server 3.17.4 from the
//! pinned peer venv) reads the version and parameters, sets one, and gets
//! its commands answered, all signed by the companion on the way.
//!
//! ```text
//! mavsdk_server (udpin) <--trusted-out-- fbwag cc --udpout--> fbwag fc-sim (udpin, --require-signed)
//! ```
//!
//! The same tool on a plain `--out` gets telemetry only: every request
//! times out (checked by hand: `--out` in place of `--trusted-out` makes
//! this test fail at `get_version`). The refusal of a trusted link on a
//! network address is tested without any peer.

use serde_json::Value;
use std::process::Command;
use std::time::Duration;

mod common;

use common::lines::LineProc;
use common::{free_port, free_tcp_port, mavsdk_server, peer_python, repo};

const KEY_HEX: &str = "77b5e1c2a0d94f3e8b6c5d4a3f2e1d0c9b8a7f6e5d4c3b2a1f0e9d8c7b6a5f4e";

fn fbwag() -> Command {
    Command::new(env!("CARGO_BIN_EXE_fbwag"))
}

/// The result of each request interop/mavsdk_gcs_check.py made.
fn calls(log: &str) -> Vec<Value> {
    log.lines()
        .filter_map(|l| serde_json::from_str::<Value>(l).ok())
        .filter(|v| v["what"] == "call")
        .collect()
}

#[test]
fn mavsdk_reads_and_commands_a_signed_fc_through_a_trusted_link() {
    let Some(py) = peer_python() else {
        return;
    };
    let (fc_port, mavsdk_port, grpc) = (free_port(), free_port(), free_tcp_port());
    let mut fc = LineProc::spawn(
        "fbwag fc-sim",
        fbwag()
            .args(["fc-sim", "--link", &format!("udpin:127.0.0.1:{fc_port}")])
            .args([
                "--sign-key",
                KEY_HEX,
                "--require-signed",
                "--duration",
                "60",
            ]),
    );
    let mut server = LineProc::spawn(
        "mavsdk_server",
        Command::new(mavsdk_server(&py))
            .args(["-p", &grpc.to_string()])
            .arg(format!("udpin://127.0.0.1:{mavsdk_port}")),
    );
    // The server before the companion: it takes the first component it
    // hears for the vehicle, and the companion speaks only once it hears
    // the FC.
    assert!(
        server.wait_for("Waiting to discover", Duration::from_secs(20)),
        "{}",
        server.log
    );
    let mut cc = LineProc::spawn(
        "fbwag cc",
        fbwag()
            .args(["cc", "--link", &format!("udpout:127.0.0.1:{fc_port}")])
            .args(["--sign-key", KEY_HEX, "--require-signed"])
            .args(["--trusted-out", &format!("udpout:127.0.0.1:{mavsdk_port}")])
            .args(["--duration", "60"]),
    );
    let mut check = LineProc::spawn(
        "mavsdk_gcs_check.py",
        Command::new(&py)
            .arg(repo().join("interop/mavsdk_gcs_check.py"))
            .args(["--grpc-port", &grpc.to_string(), "--seconds", "2"]),
    );
    let done = check.wait_exit(Duration::from_secs(90));
    for p in [&mut server, &mut cc, &mut fc] {
        p.stop();
    }
    let all = format!(
        "--- check\n{}--- fc-sim\n{}--- cc\n{}",
        check.log, fc.log, cc.log
    );
    assert!(done, "mavsdk_gcs_check.py did not end\n{all}");
    // The link that can command the aircraft is named at start.
    let trusted = format!("routing to and from udpout:127.0.0.1:{mavsdk_port}, trusted");
    assert!(cc.log.contains(&trusted), "{all}");
    let calls = calls(&check.log);
    let call = |name: &str| {
        calls
            .iter()
            .find(|c| c["call"] == name)
            .unwrap_or_else(|| panic!("no {name}\n{all}"))
            .clone()
    };
    let ok = |name: &str, value: Value| {
        let c = call(name);
        assert!(c["ok"] == true && c["value"] == value, "{name}: {c}\n{all}");
    };
    ok("get_version", serde_json::json!([4, 6, 0]));
    ok("get_param_int FS_SHORT_ACTN", 5.into());
    ok("set_param_float AIRSPEED_CRUISE 22", Value::Null);
    ok("get_param_float AIRSPEED_CRUISE", 22.0.into());
    // What decides who flies is never signed on for the trusted link: the
    // companion drops it (counted), and the FC never sees it.
    let refused = call("set_param_float FS_LONG_TIMEOUT 6");
    assert!(refused["ok"] == false, "{refused}\n{all}");
    assert!(
        !fc.log.contains("FS_LONG_TIMEOUT"),
        "the FC was asked to change FS_LONG_TIMEOUT\n{all}"
    );
    assert!(cc.log.contains("protected"), "{all}");
    // Answered, and denied: fc-sim's engine decides the modes.
    let rtl = call("return_to_launch");
    assert!(
        rtl["value"]
            .as_str()
            .unwrap_or("")
            .contains("COMMAND_DENIED"),
        "{rtl}\n{all}"
    );
}

#[test]
fn a_trusted_link_on_a_network_address_is_refused_unless_forced() {
    let cc = |extra: &[&str]| {
        let out = fbwag()
            .args(["cc", "--link", "udpout:127.0.0.1:9", "--sign-key", KEY_HEX])
            .args(extra)
            .args(["--duration", "0.2"])
            .output()
            .expect("fbwag cc");
        (
            out.status.code(),
            String::from_utf8_lossy(&out.stderr).into_owned(),
        )
    };
    for addr in ["udpin:0.0.0.0:0", "udpout:192.0.2.1:14550", "tcpin:[::]:0"] {
        let (code, err) = cc(&["--trusted-out", addr]);
        assert_eq!(code, Some(2), "{addr}: {err}");
        assert!(err.contains("not a loopback address"), "{addr}: {err}");
    }
    // Taken: the companion runs (and, no FC being there, ends with 1).
    let (code, err) = cc(&["--trusted-out", "udpin:127.0.0.1:0"]);
    assert_eq!(code, Some(1), "{err}");
    let (code, err) = cc(&[
        "--trusted-out",
        "udpout:192.0.2.1:14550",
        "--trusted-out-remote",
    ]);
    assert_eq!(code, Some(1), "{err}");
    // Without a key there is nothing to sign with.
    let out = fbwag()
        .args(["cc", "--link", "udpout:127.0.0.1:9"])
        .args(["--trusted-out", "udpin:127.0.0.1:0"])
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(2));
}
