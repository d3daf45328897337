//! Link setup for QEMU's `mps2-an386`.
//!
//! The repository's `.cargo/config.toml` links every thumbv7em binary with `-Tdefmt.x` (the
//! firmware logs with defmt). These binaries report through semihosting instead, so an empty
//! `defmt.x` is put on the linker's search path. `memory.x` (QEMU's map) is copied there too, so
//! that the board's `memory.x` in the repository root can never be picked up instead.
use std::{env, fs, path::PathBuf};

fn main() {
    let out = PathBuf::from(env::var_os("OUT_DIR").expect("cargo sets OUT_DIR"));
    let manifest = PathBuf::from(env::var_os("CARGO_MANIFEST_DIR").expect("cargo sets it"));
    let memory = manifest.join("../memory.x");
    fs::copy(&memory, out.join("memory.x")).expect("copy tests/qemu/memory.x");
    fs::write(out.join("defmt.x"), "/* empty: these binaries do not use defmt */\n")
        .expect("write defmt.x");
    println!("cargo:rustc-link-search={}", out.display());
    println!("cargo:rerun-if-changed={}", memory.display());
    println!("cargo:rerun-if-changed=build.rs");
}
