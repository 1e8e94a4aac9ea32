//! Output file names: each XML file becomes module and file `<name>.rs`,
//! with `_` appended to a Rust keyword (`fn.xml` → `fn_`, `mod.xml` →
//! `mod_`), so every module is a plain identifier and `mod.rs` stays the
//! root. Inputs that would share an output file are refused with a
//! `FILE:LINE:COL` diagnostic, and nothing is written. Driven through the
//! command line and through `Config`.

use mavgen_rs::{Config, Error};
use std::path::{Path, PathBuf};
use std::process::Command;

/// A fresh, empty directory for one test, removed when dropped.
struct TempDir(PathBuf);

impl TempDir {
    fn new(test: &str) -> Self {
        let dir =
            std::env::temp_dir().join(format!("mavgen-rs-names-{}-{test}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).expect("cannot create temp dir");
        TempDir(dir)
    }
}

impl Drop for TempDir {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

/// Writes `dir/rel`: a dialect with one message, whose id and name come
/// from `id` so that several such dialects never clash.
fn dialect(dir: &Path, rel: &str, id: u32) -> PathBuf {
    let path = dir.join(rel);
    std::fs::create_dir_all(path.parent().unwrap()).unwrap();
    std::fs::write(
        &path,
        format!(
            "<mavlink><messages>\n<message id=\"{id}\" name=\"MSG_{id}\">\
             <description>d</description>\
             <field type=\"uint8_t\" name=\"x\">x</field></message>\n\
             </messages></mavlink>\n"
        ),
    )
    .unwrap();
    path
}

/// Exit code and stderr of `mavgen-rs generate INPUTS -o OUT`, run in `dir`.
fn cli_generate(dir: &Path, inputs: &[&Path], out: &Path) -> (Option<i32>, String) {
    let output = Command::new(env!("CARGO_BIN_EXE_mavgen-rs"))
        .current_dir(dir)
        .arg("generate")
        .args(inputs)
        .arg("-o")
        .arg(out)
        .output()
        .expect("cannot run mavgen-rs");
    (
        output.status.code(),
        String::from_utf8(output.stderr).expect("stderr is not UTF-8"),
    )
}

/// The names of the files in `dir`, sorted.
fn listing(dir: &Path) -> Vec<String> {
    let mut names: Vec<String> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    names.sort();
    names
}

/// The modules `mod.rs` declares, parsed as Rust: a keyword module name
/// (`pub mod fn`) does not parse. Besides them it holds only the assertion
/// that the runtime is the one the code was generated for.
fn declared_modules(mod_rs: &str) -> Vec<String> {
    let file = syn::parse_file(mod_rs).unwrap_or_else(|e| panic!("mod.rs: {e}\n{mod_rs}"));
    file.items
        .iter()
        .filter_map(|item| match item {
            syn::Item::Mod(m) => Some(m.ident.to_string()),
            syn::Item::Const(c) if c.ident == "_" => None,
            _ => panic!("mod.rs holds something else than modules:\n{mod_rs}"),
        })
        .collect()
}

#[test]
fn keyword_file_names_become_modules_with_an_underscore() {
    let tmp = TempDir::new("keyword_cli");
    let inputs: Vec<PathBuf> = ["fn", "self", "crate", "mod", "type"]
        .iter()
        .zip(1..)
        .map(|(stem, id)| dialect(&tmp.0, &format!("{stem}.xml"), id))
        .collect();
    let inputs: Vec<&Path> = inputs.iter().map(PathBuf::as_path).collect();
    let out = tmp.0.join("out");
    let (code, stderr) = cli_generate(&tmp.0, &inputs, &out);
    assert_eq!(code, Some(0), "stderr: {stderr}");
    assert_eq!(
        listing(&out),
        [
            "crate_.rs",
            "fn_.rs",
            "mod.rs",
            "mod_.rs",
            "self_.rs",
            "type_.rs"
        ]
    );
    let mod_rs = std::fs::read_to_string(out.join("mod.rs")).unwrap();
    assert_eq!(
        declared_modules(&mod_rs),
        ["fn_", "self_", "crate_", "mod_", "type_"]
    );
    assert!(mod_rs.contains("include!(\"mod_.rs\")"), "{mod_rs}");
    let module = std::fs::read_to_string(out.join("mod_.rs")).unwrap();
    assert!(module.contains("pub struct Msg4 {"), "{module}");
}

#[test]
fn mod_xml_never_replaces_the_root_mod_rs() {
    let tmp = TempDir::new("mod_xml_config");
    let xml = dialect(&tmp.0, "mod.xml", 7);
    let out = tmp.0.join("out");
    let generated = Config::new()
        .out_dir(&out)
        .cargo_output(false)
        .compile(&[&xml])
        .unwrap_or_else(|e| panic!("{e}"));
    let names: Vec<&str> = generated
        .output
        .files
        .iter()
        .map(|(n, _)| n.as_str())
        .collect();
    assert_eq!(names, ["mod.rs", "mod_.rs"]);
    assert_eq!(listing(&out), ["mod.rs", "mod_.rs"]);
    let mod_rs = std::fs::read_to_string(out.join("mod.rs")).unwrap();
    assert_eq!(declared_modules(&mod_rs), ["mod_"]);
}

/// The diagnostics of a refused generation.
fn refused(result: Result<mavgen_rs::Generated, Error>) -> Vec<String> {
    match result {
        Err(Error::Invalid(diags)) => diags.iter().map(|d| d.to_string()).collect(),
        Err(e) => panic!("refused for another reason: {e}"),
        Ok(g) => panic!(
            "generated {:?}",
            g.output.files.iter().map(|f| &f.0).collect::<Vec<_>>()
        ),
    }
}

#[test]
fn two_inputs_with_one_output_name_are_refused_by_config() {
    let tmp = TempDir::new("same_name_config");
    // Same stem in two directories; a keyword and its escaped form; `mod`
    // and `mod_`.
    let pairs = [
        (("a/common.xml", 1), ("b/common.xml", 2), "common"),
        (("fn.xml", 3), ("fn_.xml", 4), "fn_"),
        (("mod.xml", 5), ("mod_.xml", 6), "mod_"),
    ];
    for ((first, id1), (second, id2), module) in pairs {
        let a = dialect(&tmp.0, first, id1);
        let b = dialect(&tmp.0, second, id2);
        let out = tmp.0.join(format!("out-{module}"));
        let diags = refused(
            Config::new()
                .out_dir(&out)
                .cargo_output(false)
                .compile(&[&a, &b]),
        );
        assert_eq!(diags.len(), 1, "{diags:?}");
        let expected_start = format!("{}:1:1: error: ", b.display());
        assert!(diags[0].starts_with(&expected_start), "{diags:?}");
        assert!(
            diags[0].contains(&format!(
                "would both become module `{module}` (file `{module}.rs`)"
            )),
            "{diags:?}"
        );
        assert!(!out.exists(), "{} was written", out.display());
    }
}

#[test]
fn two_inputs_with_one_output_name_are_refused_by_the_cli() {
    let tmp = TempDir::new("same_name_cli");
    let a = dialect(&tmp.0, "a/common.xml", 1);
    let b = dialect(&tmp.0, "b/common.xml", 2);
    let out = tmp.0.join("out");
    std::fs::create_dir(&out).unwrap();
    let (code, stderr) = cli_generate(&tmp.0, &[&a, &b], &out);
    assert_eq!(code, Some(1), "stderr: {stderr}");
    assert!(
        stderr.contains(&format!(
            "{}:1:1: error: {} and {} would both become module `common`",
            b.display(),
            a.display(),
            b.display()
        )),
        "stderr: {stderr}"
    );
    assert!(listing(&out).is_empty(), "wrote {:?}", listing(&out));
}

#[test]
fn an_included_keyword_file_is_referred_to_by_its_escaped_module() {
    let tmp = TempDir::new("included_keyword");
    std::fs::write(
        tmp.0.join("fn.xml"),
        "<mavlink><enums><enum name=\"MY_E\"><entry value=\"1\" name=\"MY_E_A\"/></enum></enums></mavlink>\n",
    )
    .unwrap();
    let root = tmp.0.join("root.xml");
    std::fs::write(
        &root,
        "<mavlink><include>fn.xml</include><messages>\n\
         <message id=\"2\" name=\"ROOT_M\"><field type=\"uint8_t\" name=\"e\" enum=\"MY_E\">e</field></message>\n\
         </messages></mavlink>\n",
    )
    .unwrap();
    let generated = Config::new()
        .generate(&[&root])
        .unwrap_or_else(|e| panic!("{e}"));
    let files = &generated.output.files;
    let names: Vec<&str> = files.iter().map(|(n, _)| n.as_str()).collect();
    assert_eq!(names, ["mod.rs", "root.rs", "fn_.rs"]);
    assert_eq!(declared_modules(&files[0].1), ["root", "fn_"]);
    syn::parse_file(&files[1].1).unwrap_or_else(|e| panic!("root.rs: {e}"));
    assert!(
        files[1].1.contains("pub e: super::fn_::MyE,"),
        "{}",
        files[1].1
    );
}
