//! Bindings of FBWAG_NOTICE for the `mavlink` crate, made by its own
//! generator (mavlink-bindgen 0.21), as a user of that crate would make them
//! for a custom message: the benchmarks then encode and decode the same
//! FBWAG_NOTICE frames with both libraries.
//!
//! The input is `message_definitions/fbwag.xml` without its
//! `<include>ardupilotmega.xml</include>` (the `mavlink` crate ships
//! ardupilotmega already): the same enum and message, hence the same
//! CRC_EXTRA (30; a test in `benches/tests` checks it).

use std::path::PathBuf;

fn main() {
    let xml = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../message_definitions/fbwag.xml");
    println!("cargo:rerun-if-changed={}", xml.display());
    let text = std::fs::read_to_string(&xml).expect("read message_definitions/fbwag.xml");
    let include = "<include>ardupilotmega.xml</include>";
    assert!(
        text.contains(include),
        "fbwag.xml no longer includes ardupilotmega.xml"
    );
    let out = PathBuf::from(std::env::var_os("OUT_DIR").expect("OUT_DIR"));
    let defs = out.join("definitions");
    std::fs::create_dir_all(&defs).expect("create OUT_DIR/definitions");
    let alone = defs.join("fbwag.xml");
    std::fs::write(&alone, text.replace(include, "")).expect("write fbwag.xml");
    let bindings = out.join("mavlink-bindings");
    std::fs::create_dir_all(&bindings).expect("create OUT_DIR/mavlink-bindings");
    mavlink_bindgen::generate(
        mavlink_bindgen::XmlDefinitions::Files(vec![alone]),
        &bindings,
    )
    .unwrap_or_else(|e| panic!("mavlink-bindgen: {e}"));
    // The generated `mod.rs` (the lint allowances the `mavlink` crate uses
    // for its own dialects) puts the module behind a `dialect-fbwag` feature;
    // this crate includes it unconditionally.
    let mod_rs = std::fs::read_to_string(bindings.join("mod.rs")).expect("read mod.rs");
    let gate = r#"# [cfg (feature = "dialect-fbwag")]"#;
    assert!(
        mod_rs.contains(gate),
        "unexpected mod.rs from mavlink-bindgen: {mod_rs}"
    );
    std::fs::write(bindings.join("lib.rs"), mod_rs.replace(gate, "")).expect("write lib.rs");
    // Features of the `mavlink` crate the generated code tests for; never
    // enabled here.
    println!("cargo::rustc-check-cfg=cfg(feature, values(\"serde\", \"arbitrary\", \"ts-rs\"))");
}
