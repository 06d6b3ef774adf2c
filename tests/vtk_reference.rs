//! Test 6: Classic mode without refinement is `vtkMarchingCubes`.
//!
//! An independent, straightforward re-implementation: loop over cells in
//! (k, j, i) order, case index with `s >= iso`, triangles from
//! `VTK_TRIANGLE_CASES`, a point per edge at `x0 + t (x1 - x0)` with
//! `t = (iso - s0) / (s1 - s0)` along the edge oriented as in
//! `tables::cube::EDGES`, points merged when their coordinates are
//! identical (vtkMergePoints), triangles with a repeated point dropped.
//! The library must give the same points, the same triangles and the same
//! winding, up to point numbering and triangle order.

mod common;

use std::collections::HashMap;

use common::*;
use precisemc::tables::cube::{CORNERS, EDGES};
use precisemc::tables::VTK_TRIANGLE_CASES;
use precisemc::{extract, Topology, Volume};

fn vtk_marching_cubes(
    values: &[f64],
    dims: [usize; 3],
    iso: f64,
) -> (Vec<[f64; 3]>, Vec<[u64; 3]>) {
    let mut pts: Vec<[f64; 3]> = Vec::new();
    let mut index: HashMap<[u64; 3], u64> = HashMap::new();
    let mut tris = Vec::new();
    for k in 0..dims[2] - 1 {
        for j in 0..dims[1] - 1 {
            for i in 0..dims[0] - 1 {
                let s = corners_of(values, dims, [i, j, k]);
                let mut case = 0usize;
                for (c, v) in s.iter().enumerate() {
                    if *v >= iso {
                        case |= 1 << c;
                    }
                }
                let row = &VTK_TRIANGLE_CASES[case];
                let mut n = 0;
                while n + 2 < 16 && row[n] >= 0 {
                    let mut ids = [0u64; 3];
                    for m in 0..3 {
                        let [a, b] = EDGES[row[n + m] as usize];
                        let (s0, s1) = (s[a as usize], s[b as usize]);
                        let t = (iso - s0) / (s1 - s0);
                        let (ca, cb) = (CORNERS[a as usize], CORNERS[b as usize]);
                        let x0 = [
                            (i + ca[0] as usize) as f64,
                            (j + ca[1] as usize) as f64,
                            (k + ca[2] as usize) as f64,
                        ];
                        let x1 = [
                            (i + cb[0] as usize) as f64,
                            (j + cb[1] as usize) as f64,
                            (k + cb[2] as usize) as f64,
                        ];
                        let p = [
                            x0[0] + t * (x1[0] - x0[0]),
                            x0[1] + t * (x1[1] - x0[1]),
                            x0[2] + t * (x1[2] - x0[2]),
                        ];
                        let key = p.map(|c| (c + 0.0).to_bits());
                        let next = pts.len() as u64;
                        ids[m] = *index.entry(key).or_insert_with(|| {
                            pts.push(p);
                            next
                        });
                    }
                    if ids[0] != ids[1] && ids[1] != ids[2] && ids[0] != ids[2] {
                        tris.push(ids);
                    }
                    n += 3;
                }
            }
        }
    }
    (pts, tris)
}

fn referenced_points(pts: &[[f64; 3]], tris: &[[u64; 3]]) -> Vec<[u64; 3]> {
    let mut used = vec![false; pts.len()];
    for t in tris {
        for v in t {
            used[*v as usize] = true;
        }
    }
    let p: Vec<[f64; 3]> = pts
        .iter()
        .zip(&used)
        .filter(|(_, u)| **u)
        .map(|(p, _)| *p)
        .collect();
    canonical_points(&p)
}

fn compare(name: &str, values: &[f64], dims: [usize; 3], iso: f64) {
    let (rp, rt) = vtk_marching_cubes(values, dims, iso);
    let mesh = extract(
        &Volume::new(values, dims_u64(dims)),
        iso,
        &mc_opts(Topology::Classic),
    )
    .unwrap();
    assert!(!rt.is_empty(), "{name}: empty reference");
    assert_eq!(mesh.triangles.len(), rt.len(), "{name}: triangle count");
    assert_eq!(
        referenced_points(&mesh.index_points, &mesh.triangles),
        referenced_points(&rp, &rt),
        "{name}: points differ"
    );
    assert_eq!(
        canonical_triangles(&mesh.index_points, &mesh.triangles),
        canonical_triangles(&rp, &rt),
        "{name}: triangles or winding differ"
    );
    assert!(mesh.levels.iter().all(|&l| l == 0));
    assert_eq!(mesh.stats.mc_triangles, rt.len() as u64);
}

#[test]
fn classic_equals_vtk_on_generic_fields() {
    for seed in 0..6 {
        let dims = [7, 6, 8];
        // Open surfaces too: no border.
        let mut rng = Rng::new(seed);
        let v: Vec<f64> = (0..dims[0] * dims[1] * dims[2])
            .map(|_| rng.range(-1.0, 1.0))
            .collect();
        compare(&format!("random {seed}"), &v, dims, 0.0);
        compare(&format!("random {seed} iso 0.3"), &v, dims, 0.3);
    }
    let dims = [12, 12, 12];
    compare("blobs", &blobs(dims, 5, 8), dims, 0.0);
    compare("blobs iso 0.2", &blobs(dims, 5, 8), dims, 0.2);
    compare("sphere", &sphere(dims, [5.5, 5.5, 5.5], 4.0), dims, 0.0);
}

/// Samples equal to the isovalue (integer data): points merge on samples
/// and degenerate triangles are dropped exactly as in VTK. The library
/// also removes coincident triangle pairs of opposite orientation, which
/// VTK keeps; these fields are chosen where no such pair occurs, and the
/// comparison is strict.
#[test]
fn classic_equals_vtk_with_samples_at_the_isovalue() {
    let mut compared = 0;
    for seed in 0..40 {
        let dims = [6, 5, 6];
        let mut rng = Rng::new(1000 + seed);
        let v: Vec<f64> = (0..dims[0] * dims[1] * dims[2])
            .map(|_| rng.below(4) as f64)
            .collect();
        let (rp, rt) = vtk_marching_cubes(&v, dims, 2.0);
        // Skip fields with coincident triangles in the reference.
        let c = check_tris(&rp, &rt);
        if c.duplicates != 0 {
            continue;
        }
        compare(&format!("integers {seed}"), &v, dims, 2.0);
        compared += 1;
    }
    assert!(compared >= 10, "only {compared} fields compared");
}
