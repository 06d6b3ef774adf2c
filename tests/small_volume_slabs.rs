//! Plain Marching Cubes of volumes just above the size from which helper
//! threads start (tests/determinism.rs uses smaller ones): the output is
//! bit-identical for any thread count, also with fewer cell layers than
//! threads.

mod common;
use common::*;
use precisemc::{extract, Options, Volume};

/// Plain MC of volumes just above the helpers' bound, every thread count:
/// bit-identical to one thread (including nz smaller than the threads).
#[test]
fn plain_mc_small_volumes_identical_for_any_thread_count() {
    for dims in [
        [40usize, 40, 24],
        [200, 200, 2],
        [200, 200, 3],
        [130, 130, 4],
        [34, 34, 33],
        [60, 60, 60],
    ] {
        let values = blobs(dims, 7, 12);
        let vol = Volume::new(&values, dims_u64(dims));
        for topology in TOPOLOGIES {
            let one = extract(
                &vol,
                0.0,
                &Options {
                    threads: 1,
                    ..mc_opts(topology)
                },
            )
            .unwrap();
            for t in [2, 3, 4, 5, 7, 16, 64] {
                let o = extract(
                    &vol,
                    0.0,
                    &Options {
                        threads: t,
                        ..mc_opts(topology)
                    },
                )
                .unwrap();
                assert!(same_mesh(&one, &o) && one == o, "{dims:?} {topology:?} {t}");
            }
        }
    }
}
