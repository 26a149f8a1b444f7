//! The committed header is what cbindgen generates from the source: run with
//! `MESOBAKE_BLESS=1` to rewrite it after changing the ABI.

use std::path::Path;

#[test]
fn the_header_matches_the_source() {
    let crate_dir = Path::new(env!("CARGO_MANIFEST_DIR"));
    let config = cbindgen::Config::from_file(crate_dir.join("cbindgen.toml")).unwrap();
    let mut generated = Vec::new();
    cbindgen::Builder::new()
        .with_config(config)
        .with_src(crate_dir.join("src/lib.rs"))
        .generate()
        .expect("cbindgen parses the crate")
        .write(&mut generated);
    let generated = String::from_utf8(generated).unwrap();
    let path = crate_dir.join("include/mesobake_package.h");
    if std::env::var_os("MESOBAKE_BLESS").is_some() {
        std::fs::write(&path, &generated).unwrap();
    }
    let committed = std::fs::read_to_string(&path).unwrap_or_default();
    assert!(
        committed == generated,
        "include/mesobake_package.h is stale: rerun this test with MESOBAKE_BLESS=1"
    );
}
