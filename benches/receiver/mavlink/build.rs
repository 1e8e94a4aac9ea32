//! The library linked without the C runtime's start files, as on a board.

fn main() {
    println!("cargo:rustc-cdylib-link-arg=-nostartfiles");
}
