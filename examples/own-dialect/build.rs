//! Generates the dialect of `my_dialect.xml` (and `common.xml`, which it
//! includes) into `OUT_DIR`; `src/main.rs` includes it.

fn main() {
    mavgen_rs::Config::new()
        .compile(&["my_dialect.xml"])
        .unwrap_or_else(|e| panic!("{e}"));
}
