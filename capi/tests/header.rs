//! The committed header is what cbindgen generates from the crate today: a change to the
//! ABI that forgot the header fails here. `STEREOTRACE_BLESS=1` rewrites the header.

use std::path::Path;

#[test]
fn the_committed_header_is_the_generated_one() {
    let crate_dir = Path::new(env!("CARGO_MANIFEST_DIR"));
    let config = cbindgen::Config::from_file(crate_dir.join("cbindgen.toml")).expect("cbindgen.toml parses");
    let mut generated = Vec::new();
    cbindgen::Builder::new()
        .with_crate(crate_dir)
        .with_config(config)
        .generate()
        .expect("cbindgen generates the header")
        .write(&mut generated);
    let generated = String::from_utf8(generated).expect("the header is UTF-8");
    let path = crate_dir.join("include/stereotrace.h");
    if std::env::var_os("STEREOTRACE_BLESS").is_some() {
        std::fs::write(&path, &generated).expect("write the header");
        return;
    }
    let committed = std::fs::read_to_string(&path).unwrap_or_default();
    assert!(
        committed == generated,
        "capi/include/stereotrace.h is out of date with capi/src; regenerate it with \
         STEREOTRACE_BLESS=1 cargo test -p stereotrace-capi --test header"
    );
}
