//! Generates the FBWAG dialect from `message_definitions/fbwag.xml` into
//! `OUT_DIR` (included by `src/lib.rs`).

fn main() {
    let xml = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../message_definitions/fbwag.xml"
    );
    println!("cargo:rerun-if-changed={xml}");
    // Not `cargo_output(true)`: that would also repeat, on every build, the one
    // warning this dialect always has. FBWAG_NOTICE's system_id/component_id
    // are the paper's wire definition (hashed into CRC_EXTRA 30); their clash
    // with the official C generator is documented in
    // docs/c-generator-name-clash.md and cannot be fixed here.
    let generated = mavgen::Config::new()
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
