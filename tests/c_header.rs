//! The committed C header `include/precisemc.h` must be exactly what
//! cbindgen generates from `src/ffi` with `cbindgen.toml`, and its version
//! macros must match the crate version.
//!
//! Regenerate it with `PMC_UPDATE_HEADER=1 cargo test --test c_header`.

use std::path::PathBuf;

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

/// The version macros injected after the includes.
fn version_macros() -> String {
    format!(
        "\n#define PMC_VERSION_MAJOR {}\n#define PMC_VERSION_MINOR {}\n#define PMC_VERSION_PATCH {}\n#define PMC_VERSION_STRING \"{}\"",
        env!("CARGO_PKG_VERSION_MAJOR"),
        env!("CARGO_PKG_VERSION_MINOR"),
        env!("CARGO_PKG_VERSION_PATCH"),
        env!("CARGO_PKG_VERSION"),
    )
}

fn generate() -> String {
    let root = root();
    let mut config =
        cbindgen::Config::from_file(root.join("cbindgen.toml")).expect("cbindgen.toml");
    let mut after = config.after_includes.take().unwrap_or_default();
    after.push_str(&version_macros());
    config.after_includes = Some(after);
    let bindings = cbindgen::Builder::new()
        .with_config(config)
        .with_src(root.join("src/ffi/mod.rs"))
        .generate()
        .expect("cbindgen failed on src/ffi");
    let mut out = Vec::new();
    bindings.write(&mut out);
    String::from_utf8(out).expect("header is UTF-8")
}

fn header_path() -> PathBuf {
    root().join("include/precisemc.h")
}

fn updating() -> bool {
    std::env::var_os("PMC_UPDATE_HEADER").is_some()
}

/// The committed header (the freshly generated one while updating, since
/// the tests run concurrently with the writer).
fn header() -> String {
    if updating() {
        generate()
    } else {
        std::fs::read_to_string(header_path()).expect("include/precisemc.h")
    }
}

#[test]
fn committed_header_is_up_to_date() {
    let generated = generate();
    let path = header_path();
    if updating() {
        std::fs::create_dir_all(path.parent().unwrap()).unwrap();
        std::fs::write(&path, &generated).unwrap();
        return;
    }
    let committed = std::fs::read_to_string(&path)
        .unwrap_or_else(|e| panic!("cannot read {}: {e}", path.display()));
    if committed != generated {
        let first = committed
            .lines()
            .zip(generated.lines())
            .position(|(a, b)| a != b)
            .unwrap_or(committed.lines().count().min(generated.lines().count()));
        panic!(
            "{} is out of date (first difference at line {}); regenerate it with \
             `PMC_UPDATE_HEADER=1 cargo test --test c_header` and never edit it by hand",
            path.display(),
            first + 1
        );
    }
}

fn define(header: &str, name: &str) -> String {
    let prefix = format!("#define {name} ");
    header
        .lines()
        .find_map(|l| l.strip_prefix(&prefix))
        .unwrap_or_else(|| panic!("no #define {name} in the header"))
        .trim()
        .to_string()
}

#[test]
fn version_macros_match_the_crate() {
    let header = header();
    let version = env!("CARGO_PKG_VERSION");
    let mut parts = version.split(['.', '-', '+']);
    for name in [
        "PMC_VERSION_MAJOR",
        "PMC_VERSION_MINOR",
        "PMC_VERSION_PATCH",
    ] {
        assert_eq!(define(&header, name), parts.next().unwrap(), "{name}");
    }
    assert_eq!(
        define(&header, "PMC_VERSION_STRING"),
        format!("\"{version}\"")
    );
    // The loaded library reports the same version.
    let s = unsafe { std::ffi::CStr::from_ptr(precisemc::ffi::pmc_version_string()) };
    assert_eq!(s.to_str().unwrap(), version);
}

#[test]
fn header_is_self_contained_c() {
    // Cheap sanity checks; the C tests compile it for real.
    let header = header();
    assert!(header.contains("#ifndef PRECISEMC_H"));
    assert!(header.contains("extern \"C\""));
    assert!(
        !header.contains("Pmc"),
        "a Rust-only name leaked into the header"
    );
    for f in [
        "pmc_extract",
        "pmc_status_string",
        "pmc_last_error_message",
        "pmc_mesh_stats",
    ] {
        assert!(header.contains(f), "{f} missing");
    }
}
