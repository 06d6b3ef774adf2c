//! Plain Marching Cubes of volumes just above the size from which helper
//! threads start (tests/determinism.rs uses smaller ones): the output,
//! normals and gradients included, is
//! bit-identical for any thread count, also with fewer cell layers than
//! threads.

mod common;
use common::*;
use precisemc::{extract, NormalMode, Options, Topology, Volume};

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
        // blobs() sets the border below the isovalue: a volume 2 to 4
        // samples thick would hold little or no surface. Waves cross every
        // layer instead.
        let values = if dims[2] <= 4 {
            grid_fn(dims, |x, y, z| {
                (0.31 * x).sin() + (0.23 * y).cos() + 0.5 * z - 0.6
            })
        } else {
            blobs(dims, 7, 12)
        };
        let vol = Volume::new(&values, dims_u64(dims));
        // Normals and gradients too (computed on the helper threads): the
        // volumes of tests/determinism.rs run on the calling thread alone.
        let modes = [
            NormalMode::None,
            NormalMode::Gradient,
            NormalMode::CentralDifference,
        ];
        for (topology, normals) in TOPOLOGIES
            .into_iter()
            .zip(modes)
            .chain([(Topology::Trilinear, modes[2])])
        {
            let run = |threads| {
                extract(
                    &vol,
                    0.0,
                    &Options {
                        threads,
                        normals,
                        gradients: normals != NormalMode::None,
                        ..mc_opts(topology)
                    },
                )
                .unwrap()
            };
            let one = run(1);
            assert!(
                one.triangles.len() > 100,
                "{dims:?} {topology:?}: only {} triangles",
                one.triangles.len()
            );
            assert_eq!(one.normals.is_empty(), normals == NormalMode::None);
            assert_eq!(one.gradients.is_empty(), normals == NormalMode::None);
            for t in [2, 3, 4, 5, 7, 16, 64] {
                let o = run(t);
                assert!(
                    same_mesh(&one, &o) && one == o,
                    "{dims:?} {topology:?} {normals:?} {t}"
                );
            }
        }
    }
}
