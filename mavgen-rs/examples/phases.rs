//! Times the generator's phases on one XML file (load+check, render).
use std::time::Instant;
fn main() {
    let xml = std::env::args().nth(1).expect("usage: phases XML");
    let t = Instant::now();
    let schema = mavgen_rs::Schema::load(&[&xml]).expect("valid");
    let load = t.elapsed();
    let t = Instant::now();
    let generated = mavgen_rs::Config::new()
        .generate_from(&schema)
        .expect("generates");
    let render = t.elapsed();
    let bytes: usize = generated.output.files.iter().map(|(_, t)| t.len()).sum();
    println!("load+check {load:?}, render {render:?}, {bytes} bytes");
}
