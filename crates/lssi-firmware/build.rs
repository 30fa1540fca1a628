//! Puts the repository's `memory.x` (the one source of the memory map) on the linker's
//! search path and passes the linker scripts of cortex-m-rt and defmt.
//!
//! Keep no `memory.x` in this crate's root: the linker runs in the crate directory and
//! would pick that one up before the copy in `OUT_DIR`.

use std::{env, fs, path::PathBuf};

fn main() {
    let manifest_dir = PathBuf::from(env::var_os("CARGO_MANIFEST_DIR").expect("set by cargo"));
    let out_dir = PathBuf::from(env::var_os("OUT_DIR").expect("set by cargo"));
    let source = manifest_dir.join("../../memory.x");

    let memory_x = fs::read(&source)
        .unwrap_or_else(|e| panic!("cannot read the memory map {}: {e}", source.display()));
    fs::write(out_dir.join("memory.x"), memory_x).expect("OUT_DIR is writable");

    println!("cargo:rustc-link-search={}", out_dir.display());
    println!("cargo:rerun-if-changed={}", source.display());
    println!("cargo:rerun-if-changed=build.rs");

    // Only the firmware binary links a whole image (`link.x` includes `memory.x`).
    println!("cargo:rustc-link-arg-bins=--nmagic");
    println!("cargo:rustc-link-arg-bins=-Tlink.x");
    println!("cargo:rustc-link-arg-bins=-Tdefmt.x");
}
