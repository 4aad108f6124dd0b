//! `include/tilegraph.h` is what cbindgen makes of this crate now: a change to the C ABI
//! without a regenerated header fails here. `TILEGRAPH_BLESS=1` rewrites the header.

use std::path::Path;

#[test]
fn header_is_current() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR"));
    let config = cbindgen::Config::from_file(dir.join("cbindgen.toml")).unwrap();
    let mut generated = Vec::new();
    cbindgen::Builder::new()
        .with_crate(dir)
        .with_config(config)
        .generate()
        .unwrap()
        .write(&mut generated);
    let generated = String::from_utf8(generated).unwrap();
    let path = dir.join("include/tilegraph.h");
    if std::env::var_os("TILEGRAPH_BLESS").is_some() {
        std::fs::write(&path, &generated).unwrap();
        return;
    }
    let committed = std::fs::read_to_string(&path).unwrap_or_default();
    assert!(
        committed == generated,
        "{} is stale: regenerate it with `TILEGRAPH_BLESS=1 cargo test -p tilegraph-capi --test header`",
        path.display()
    );
}
