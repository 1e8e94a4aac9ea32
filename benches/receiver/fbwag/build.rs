//! A dialect of HEARTBEAT alone, from minimal.xml; the library linked
//! without the C runtime's start files, as on a board.

fn main() {
    println!("cargo:rustc-cdylib-link-arg=-nostartfiles");
    mavgen_rs::Config::new()
        .messages(["HEARTBEAT"])
        .compile(&["../../../message_definitions/minimal.xml"])
        .unwrap_or_else(|e| panic!("{e}"));
}
