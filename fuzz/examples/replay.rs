//! Replays inputs through a harness, printing the decoded case first:
//! `cargo run --example replay -- core|c_api FILE...` (a FILE of the form
//! `hex:0a1b...` is read as hexadecimal bytes).
fn main() {
    let mut args = std::env::args().skip(1);
    let target = args.next().expect("core or c_api");
    for f in args {
        let data = match f.strip_prefix("hex:") {
            Some(h) => (0..h.len() / 2)
                .map(|i| u8::from_str_radix(&h[2 * i..2 * i + 2], 16).unwrap())
                .collect(),
            None => std::fs::read(&f).unwrap(),
        };
        let mut r = precisemc_fuzz::Reader::new(&data);
        let case = precisemc_fuzz::decode_case(&mut r, target == "c_api");
        let (opts, err) = precisemc_fuzz::decode_options(&mut r);
        eprintln!(
            "{f}: dims {:?} iso {:e} closed {} strides {:?} offset {} origin {:?} spacing {:?} index_offset {:?}",
            case.dims, case.iso, case.closed, case.strides, case.offset, case.origin, case.spacing, case.index_offset
        );
        let vals: Vec<f64> = (0..case.contiguous.len())
            .map(|i| case.contiguous.get(i))
            .collect();
        eprintln!(
            "type {:?}\nvalues {:?}",
            std::mem::discriminant(&case.contiguous),
            vals
        );
        eprintln!("options {opts:?} (error {err:?})");
        match target.as_str() {
            "core" => precisemc_fuzz::fuzz_core(&data),
            _ => precisemc_fuzz::fuzz_c_api(&data),
        }
        eprintln!("{f}: ok");
    }
}
