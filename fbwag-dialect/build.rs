//! Generates the FBWAG dialect from `message_definitions/fbwag.xml` into
//! `OUT_DIR` (included by `src/lib.rs`).
//!
//! A filtered build generates only some messages (and the enums they use):
//! the `cc-subset` feature selects what a companion computer speaks, and the
//! environment variable `FBWAG_DIALECT_MESSAGES=A,B,…` any list. FBWAG_NOTICE
//! and HEARTBEAT are always kept (the crate's API re-exports them). Frames of
//! other messages still parse, as raw frames.

/// What the companion computer of the paper sends and reads.
const CC_SUBSET: &[&str] = &[
    "HEARTBEAT",
    "FBWAG_NOTICE",
    "RC_CHANNELS_OVERRIDE",
    "SET_ATTITUDE_TARGET",
    "STATUSTEXT",
    "COMMAND_LONG",
    "COMMAND_ACK",
    "SYS_STATUS",
    "ATTITUDE",
    "GLOBAL_POSITION_INT",
    "RC_CHANNELS",
    "VFR_HUD",
];

fn main() {
    let xml = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../message_definitions/fbwag.xml"
    );
    println!("cargo:rerun-if-changed={xml}");
    println!("cargo:rerun-if-env-changed=FBWAG_DIALECT_MESSAGES");
    let mut config = mavgen::Config::new();
    let env_list = std::env::var("FBWAG_DIALECT_MESSAGES")
        .ok()
        .filter(|s| !s.trim().is_empty());
    let filter: Option<Vec<String>> = match env_list {
        Some(list) => Some(list.split(',').map(|s| s.trim().to_string()).collect()),
        None if std::env::var_os("CARGO_FEATURE_CC_SUBSET").is_some() => {
            Some(CC_SUBSET.iter().map(|s| s.to_string()).collect())
        }
        None => None,
    };
    if let Some(mut names) = filter {
        for keep in ["FBWAG_NOTICE", "HEARTBEAT"] {
            if !names.iter().any(|n| n == keep) {
                names.push(keep.into());
            }
        }
        config.messages(names);
    }
    // Not `cargo_output(true)`: that would also repeat, on every build, the one
    // warning this dialect always has. FBWAG_NOTICE's system_id/component_id
    // are the paper's wire definition (hashed into CRC_EXTRA 30); their clash
    // with the official C generator is documented in
    // docs/c-generator-name-clash.md and cannot be fixed here.
    let generated = config
        .cargo_output(false)
        .compile(&[xml])
        .unwrap_or_else(|e| {
            eprintln!("{e}");
            std::process::exit(1);
        });
    for input in &generated.inputs {
        println!("cargo:rerun-if-changed={}", input.display());
    }
}
