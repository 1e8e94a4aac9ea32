//! With the `codegen` feature: generates the FBWAG dialect from
//! `message_definitions/fbwag.xml` into `OUT_DIR` (included by `src/lib.rs`).
//! The crate's `message_definitions/` holds fbwag.xml and exactly the files
//! it includes: symbolic links to the workspace's `message_definitions/` in
//! the repository (one copy of the protocol data), which `cargo package`
//! stores as files, so a published crate generates from its own copy.
//! Without it there is nothing to do: the crate compiles the checked-in
//! `bindings/fbwag`, the very same code.
//!
//! A filtered build generates only some messages (and the enums they use):
//! the environment variable `FBWAG_DIALECT_MESSAGES=A,B,…` lists them (the
//! companion computer's fixed subset is the crate `fbwag-dialect-cc`).
//! FBWAG_NOTICE and HEARTBEAT are always kept (the crate's API re-exports
//! them). Frames of other messages still parse, as raw frames.

fn main() {
    println!("cargo:rerun-if-changed=build.rs");
    println!("cargo:rerun-if-env-changed=FBWAG_DIALECT_MESSAGES");
    #[cfg(feature = "codegen")]
    codegen();
    #[cfg(not(feature = "codegen"))]
    if std::env::var("FBWAG_DIALECT_MESSAGES").is_ok_and(|s| !s.trim().is_empty()) {
        println!(
            "cargo:warning=FBWAG_DIALECT_MESSAGES is ignored: a custom message list needs \
             fbwag-dialect's `codegen` feature (the checked-in bindings are compiled)"
        );
    }
}

#[cfg(feature = "codegen")]
fn codegen() {
    let dir = env!("CARGO_MANIFEST_DIR");
    let xml = std::path::PathBuf::from(format!("{dir}/message_definitions/fbwag.xml"));
    if !xml.is_file() {
        // A dangling link (the crate directory copied out of the
        // repository alone): name the file rather than a generator error.
        eprintln!(
            "fbwag-dialect (feature codegen): {} is missing; in the repository it is a \
             symbolic link to ../message_definitions/fbwag.xml (a checkout needs \
             symbolic links enabled, e.g. git's core.symlinks on Windows)",
            xml.display()
        );
        std::process::exit(1);
    }
    let mut config = mavgen_rs::Config::new();
    let filter: Option<Vec<String>> = std::env::var("FBWAG_DIALECT_MESSAGES")
        .ok()
        .filter(|s| !s.trim().is_empty())
        .map(|list| list.split(',').map(|s| s.trim().to_string()).collect());
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
