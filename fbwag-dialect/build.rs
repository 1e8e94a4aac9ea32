//! Generates the FBWAG dialect from `message_definitions/fbwag.xml` into
//! `OUT_DIR` (included by `src/lib.rs`).

fn main() {
    let xml = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../message_definitions/fbwag.xml"
    );
    let mut config = mavgen::Config::new();
    // FBWAG_NOTICE's system_id/component_id names are the paper's wire
    // definition (they are hashed into CRC_EXTRA); the C-generator clash they
    // cause is documented in docs/c-generator-name-clash.md, not fixable here.
    config.cargo_output(true);
    if let Err(e) = config.compile(&[xml]) {
        eprintln!("{e}");
        std::process::exit(1);
    }
}
