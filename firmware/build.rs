//! Puts the root `memory.x` on the linker search path for embedded builds.
use std::{env, fs, path::PathBuf};

fn main() {
    let target = env::var("TARGET").unwrap_or_default();
    println!("cargo:rerun-if-changed=../memory.x");
    println!("cargo:rerun-if-changed=build.rs");
    if !target.starts_with("thumb") {
        return;
    }
    let out = PathBuf::from(env::var_os("OUT_DIR").unwrap_or_default());
    let src = PathBuf::from(env::var_os("CARGO_MANIFEST_DIR").unwrap_or_default()).join("../memory.x");
    if let Err(e) = fs::copy(&src, out.join("memory.x")) {
        println!("cargo:warning=cannot copy {}: {e}", src.display());
    }
    println!("cargo:rustc-link-search={}", out.display());
}
