//! Build script: gives the shared library an ELF SONAME when the build asks
//! for one through `PRECISEMC_SONAME` (the CMake build does, with
//! `libprecisemc.so.<major>.<minor>` before 1.0). A plain `cargo build`
//! leaves the library without one, so that programs linked against cargo's
//! `target/release/libprecisemc.so` find it under that name.

fn main() {
    println!("cargo:rerun-if-changed=build.rs");
    println!("cargo:rerun-if-env-changed=PRECISEMC_SONAME");
    let soname = std::env::var("PRECISEMC_SONAME").unwrap_or_default();
    if soname.is_empty() {
        return;
    }
    // Only ELF platforms have a SONAME (Mach-O has an install name and
    // Windows DLLs neither).
    let os = std::env::var("CARGO_CFG_TARGET_OS").unwrap_or_default();
    let family = std::env::var("CARGO_CFG_TARGET_FAMILY").unwrap_or_default();
    let elf = family.split(',').any(|f| f == "unix") && !matches!(os.as_str(), "macos" | "ios");
    if !elf {
        println!("cargo:warning=PRECISEMC_SONAME ignored: the target ({os}) is not ELF");
        return;
    }
    // A name with a path or spaces would be a mistake in the caller.
    if soname.contains(['/', ' ', ',']) {
        panic!("PRECISEMC_SONAME must be a plain file name, not {soname:?}");
    }
    println!("cargo:rustc-cdylib-link-arg=-Wl,-soname,{soname}");
}
