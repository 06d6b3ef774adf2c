//! Debug aid: runs the pseudo-random inputs of `tests/fuzz_corpus.rs`
//! (`cargo run --example explore -- core|c_api SEED COUNT`).
fn main() {
    let a: Vec<String> = std::env::args().collect();
    let f = if a[1] == "core" {
        precisemc_fuzz::fuzz_core
    } else {
        precisemc_fuzz::fuzz_c_api
    };
    let seed: u64 = a[2].parse().unwrap();
    let count: usize = a[3].parse().unwrap();
    let start: usize = a.get(4).map_or(0, |x| x.parse().unwrap());
    let only: Vec<usize> = a.get(5).map_or(vec![], |x| {
        x.split(',').map(|y| y.parse().unwrap()).collect()
    });
    let mut s = seed;
    let mut next = || {
        s = s.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = s;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    };
    for i in 0..count {
        let len = (next() % 301) as usize;
        let data: Vec<u8> = (0..len).map(|_| next() as u8).collect();
        if i < start && !only.contains(&i) {
            continue;
        }
        eprintln!("input {i}");
        if let Ok(dir) = std::env::var("SAVE_TO") {
            std::fs::write(format!("{dir}/input-{i}"), &data).unwrap();
        }
        f(&data);
    }
}
