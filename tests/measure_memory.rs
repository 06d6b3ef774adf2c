//! The accuracy measure's memory stays bounded however much of the volume
//! straddles the isovalue. In a file of its own: the peak resident size
//! of the process is read, which other tests running beside it would
//! raise.

use precisemc::accuracy::{measure, MeasureOptions};
use precisemc::Volume;

/// The process's peak resident size (VmHWM), in bytes.
fn peak() -> u64 {
    let status = std::fs::read_to_string("/proc/self/status").unwrap();
    let line = status.lines().find(|l| l.starts_with("VmHWM:")).unwrap();
    let kib: u64 = line.split_whitespace().nth(1).unwrap().parse().unwrap();
    kib * 1024
}

/// A volume every sample of which is the isovalue (S_K fills it) and a
/// triangle 300 cells below it: every cell within the search's radius
/// straddles. The search pushed them all at once (1.35 GB for this one
/// triangle, 20 s; a host with less memory was aborted); blocks of cells
/// now wait as one entry until they come first.
#[test]
fn a_volume_full_of_surface_measures_in_little_memory() {
    if !std::path::Path::new("/proc/self/status").exists() {
        return;
    }
    let n = 256u64;
    let data = vec![7u8; (n * n * n) as usize];
    let vol = Volume::new(&data, [n, n, n]);
    let points = [
        [100.0, 120.0, -300.0],
        [101.0, 120.0, -300.0],
        [100.0, 121.0, -300.0],
    ];
    let before = peak();
    let opts = MeasureOptions {
        density: 1,
        ..MeasureOptions::default()
    };
    let d = measure(&vol, 7.0, &points, &[[0, 1, 2]], &opts).unwrap();
    let grown = peak().saturating_sub(before);
    assert_eq!(d.samples, 3);
    assert!((d.max - 300.0).abs() <= 1e-5 + 0.02 * 300.0, "{d:?}");
    assert!(grown < 200 << 20, "the peak grew by {} MiB", grown >> 20);
}
