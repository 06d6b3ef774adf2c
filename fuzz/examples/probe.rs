//! Debug aid: decodes a core input and reports, for several option sets,
//! whether the mesh is closed (`cargo run --example probe -- hex:...`).
use precisemc::{extract, Options, Rule, Topology};
fn main() {
    let f = std::env::args().nth(1).unwrap();
    let data: Vec<u8> = match f.strip_prefix("hex:") {
        Some(h) => (0..h.len() / 2)
            .map(|i| u8::from_str_radix(&h[2 * i..2 * i + 2], 16).unwrap())
            .collect(),
        None => std::fs::read(&f).unwrap(),
    };
    std::panic::set_hook(Box::new(|_| {}));
    let clamp: f64 = std::env::args()
        .nth(2)
        .map_or(f64::INFINITY, |s| s.parse().unwrap());
    let mut r = precisemc_fuzz::Reader::new(&data);
    let mut case = precisemc_fuzz::decode_case(&mut r, false);
    for i in 0..case.contiguous.len() {
        let v = case.contiguous.get(i);
        case.contiguous.set(i, v.clamp(-clamp, clamp));
    }
    let (base, _) = precisemc_fuzz::decode_options(&mut r);
    for top in [Topology::Classic, Topology::Trilinear] {
        for (eps, lvl, cap) in [(0.0, 0, 0), (0.01, 1, 0), (0.01, 3, 0), (5e-324, 7, 5000)] {
            for rule in [Rule::A, Rule::A1, Rule::A2, Rule::B] {
                let o = Options {
                    epsilon: eps,
                    max_level: lvl,
                    max_triangles: cap,
                    topology: top,
                    rule,
                    threads: 1,
                    ..base.clone()
                };
                let m = extract(&case.contiguous_volume(), case.iso, &o).unwrap();
                let ok = std::panic::catch_unwind(|| precisemc_fuzz::check_closed(&m)).is_ok();
                println!("{top:?} eps {eps:e} level {lvl} cap {cap} {rule:?}: {} tris, eff level {}, closed {ok}", m.triangles.len(), m.stats.effective_max_level);
            }
        }
    }
}
