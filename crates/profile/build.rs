//! Embeds every `config/profiles/*.toml` into the library, so a binary needs no files at run time.
//! The list is generated here rather than written by hand, so adding a profile is adding a file.

use std::{env, fs, path::PathBuf};

fn main() {
    let manifest = PathBuf::from(env::var_os("CARGO_MANIFEST_DIR").unwrap_or_default());
    let dir = manifest.join("../../config/profiles");
    println!("cargo:rerun-if-changed={}", dir.display());
    let mut files: Vec<PathBuf> = match fs::read_dir(&dir) {
        Ok(rd) => rd
            .filter_map(|e| e.ok().map(|e| e.path()))
            .filter(|p| p.extension().is_some_and(|x| x == "toml"))
            .collect(),
        Err(e) => {
            println!(
                "cargo:warning=no profile directory at {}: {e}",
                dir.display()
            );
            Vec::new()
        }
    };
    files.sort();
    let mut out = String::from(
        "/// (file name, TOML text) of every embedded profile, sorted by file name.\n",
    );
    out.push_str("pub(crate) const EMBEDDED: &[(&str, &str)] = &[\n");
    for f in &files {
        println!("cargo:rerun-if-changed={}", f.display());
        let name = f.file_name().and_then(|n| n.to_str()).unwrap_or_default();
        let abs = fs::canonicalize(f).unwrap_or_else(|_| f.clone());
        out.push_str(&format!(
            "    ({name:?}, include_str!({:?})),\n",
            abs.display().to_string()
        ));
    }
    out.push_str("];\n");
    let out_dir = PathBuf::from(env::var_os("OUT_DIR").unwrap_or_default());
    if let Err(e) = fs::write(out_dir.join("embedded_profiles.rs"), out) {
        println!("cargo:warning=cannot write embedded profile list: {e}");
        std::process::exit(1);
    }
}
