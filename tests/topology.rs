//! Test 2: the topology of Trilinear-mode meshes against the exact
//! isosurface of the trilinear interpolant, measured independently on a
//! dense sampling.
//!
//! Single cell. Write P = {F >= 0}, N = {F < 0} in the cell (a ball).
//! Every connected surface component separates the ball into two parts,
//! so the adjacency graph of the regions (components of P and N) is a tree
//! whose edges are the surface components:
//! `#components = #P regions + #N regions - 1`. Likewise on the cube's
//! surface (a sphere) the curve F = 0 has `#surface regions - 1` loops, and
//! each loop lies on the component that separates the 3D regions of its
//! two sides, which gives the number of loops of every component. The
//! trilinear isosurface in a cell has genus 0 components, so its Euler
//! characteristic is `sum(2 - loops)`. All of this is measured by flood
//! fills of a (48+1)^3 sampling (40 for the random cells) (the reference checks its own consistency:
//! both adjacency graphs must be trees) and compared with the mesh's
//! components, boundary loops per component and V - E + F. Cells where a
//! corner value or a critical value of F (face saddles, interior critical
//! points) is within 1e-2 (relative) of the isovalue are skipped as
//! degenerate for the reference (at 40 samples per edge a closer saddle
//! can make a neck thinner than the sampling); the hand-made MC33
//! configurations are at least 5e-3 away and use 48 samples.
//!
//! Volumes. With the border below the isovalue the surface is closed and,
//! by the same argument in R^3 (Jordan-Brouwer), `#components = #P
//! components + #N components - 1`. Its Euler characteristic is `2
//! chi(P)` (P is a compact 3-manifold bounded by the surface), and chi(P)
//! is measured as the Euler characteristic of the cubical complex of the
//! inside samples of a fine sampling.

mod common;

use common::*;
use precisemc::mc::trilinear::face_decisions;
use precisemc::tables::cube::{face_is_ambiguous, FACES};
use precisemc::{extract, Options, Reconstruction, Rule, Topology, Volume};

fn cell_mesh_check(f: &[f64; 8]) -> MeshCheck {
    let data = cell_volume(f);
    let mesh = extract(
        &Volume::new(&data, [2, 2, 2]),
        0.0,
        &mc_opts(Topology::Trilinear),
    )
    .unwrap();
    check_mesh(&mesh)
}

fn compare_cell(f: &[f64; 8], r: &CellReference) -> Result<(), String> {
    let c = cell_mesh_check(f);
    if c.components != r.components
        || c.loops_per_component != r.loops_per_component
        || c.euler != r.euler
    {
        return Err(format!(
            "mesh: {} components, loops {:?}, chi {}; reference: {} components, loops {:?}, chi {} ({} inside, {} outside regions)",
            c.components,
            c.loops_per_component,
            c.euler,
            r.components,
            r.loops_per_component,
            r.euler,
            r.inside_regions,
            r.outside_regions
        ));
    }
    if c.nonmanifold_edges != 0 || c.misoriented_edges != 0 || c.degenerate != 0 {
        return Err(format!("bad patch {c:?}"));
    }
    Ok(())
}

/// Hand-made and searched configurations of the Marching Cubes 33 cases
/// with interior ambiguity, each with its expected reference signature
/// (loops per component, inside regions, outside regions). Names follow
/// Chernyaev's numbering as far as the signature identifies the subcase.
#[allow(clippy::type_complexity)]
const MC33: &[(&str, [f64; 8], &[usize], usize, usize)] = &[
    // Case 4: corners 0 and 6 inside (body diagonal).
    (
        "4.1.1 two disks",
        [5.061, -1.632, -3.345, -3.429, -3.638, -2.069, 3.096, -2.388],
        &[1, 1],
        2,
        1,
    ),
    (
        "4.1.2 tunnel",
        [7.53, -2.463, -0.71, -1.835, -1.432, -0.523, 8.61, -1.062],
        &[2],
        1,
        1,
    ),
    (
        "4.1.2 tunnel (symmetric)",
        [1.0, -0.2, -0.2, -0.2, -0.2, -0.2, 1.0, -0.2],
        &[2],
        1,
        1,
    ),
    // Case 6: corners 0, 1 and 6 inside; face x = 1 ambiguous.
    (
        "6.1.1",
        [0.062, 0.337, -0.685, -0.062, -0.095, -0.43, 0.388, -0.182],
        &[1, 1],
        2,
        1,
    ),
    (
        "6.1.2 tunnel",
        [2.202, 0.082, -1.418, -0.117, -0.129, -0.994, 1.183, -0.087],
        &[2],
        1,
        1,
    ),
    (
        "6.2",
        [2.214, 3.187, -1.417, -0.576, -0.85, -0.7, 1.598, -0.783],
        &[1],
        1,
        1,
    ),
    // Case 7: corners 1, 3 and 4 inside; three ambiguous faces.
    (
        "7.1",
        [-2.423, 0.167, -0.285, 0.228, 0.351, -1.803, -1.891, -0.998],
        &[1, 1, 1],
        3,
        1,
    ),
    (
        "7.2 a",
        [-2.529, 4.063, -0.658, 5.964, 0.434, -4.997, -0.877, -5.341],
        &[1, 1],
        2,
        1,
    ),
    (
        "7.2 b",
        [-0.717, 0.132, -0.574, 0.106, 1.221, -0.06, -0.054, -1.39],
        &[1, 1],
        2,
        1,
    ),
    (
        "7.2 c",
        [-0.384, 0.17, -1.993, 0.363, 1.331, -1.905, -0.368, -0.332],
        &[1, 1],
        2,
        1,
    ),
    (
        "7.3 a",
        [
            -6.657, 10.747, -3.375, 3.963, 5.753, -2.711, -1.419, -11.928,
        ],
        &[1],
        1,
        1,
    ),
    (
        "7.3 b",
        [-1.292, 0.936, -0.406, 3.801, 1.851, -5.019, -0.332, -0.888],
        &[1],
        1,
        1,
    ),
    (
        "7.3 c",
        [-0.13, 0.354, -2.885, 0.161, 2.508, -1.101, -0.133, -0.184],
        &[1],
        1,
        1,
    ),
    (
        "7.4.1",
        [-0.297, 1.1, -1.181, 2.851, 2.836, -1.466, -1.611, -2.016],
        &[1, 1],
        1,
        2,
    ),
    (
        "7.4.2 tunnel",
        [-3.44, 2.779, -0.231, 0.933, 5.096, -2.584, -5.138, -0.586],
        &[2],
        1,
        1,
    ),
    // Case 10: corners 0, 2, 4, 6 inside; faces z = 0 and z = 1 ambiguous.
    (
        "10.1.1 separated",
        [0.297, -0.794, 1.216, -1.273, 1.011, -1.017, 0.21, -0.402],
        &[1, 1],
        2,
        1,
    ),
    (
        "10.1.1 joined",
        [0.53, -0.341, 0.787, -0.551, 0.766, -0.06, 0.147, -0.121],
        &[1, 1],
        1,
        2,
    ),
    (
        "10.1.2 tunnel",
        [3.395, -0.725, 0.063, -1.257, 0.076, -0.594, 1.986, -1.405],
        &[2],
        1,
        1,
    ),
    (
        "10.1.2 tunnel (hand-made)",
        [4.0, -1.5, 0.25, -1.5, 0.25, -1.5, 4.0, -1.5],
        &[2],
        1,
        1,
    ),
    (
        "10.1.2 tunnel (outside)",
        [0.865, -1.32, 0.675, -0.073, 1.691, -0.401, 0.802, -2.65],
        &[2],
        1,
        1,
    ),
    (
        "10.2 a",
        [0.157, -1.119, 0.256, -0.198, 0.62, -0.344, 0.896, -0.22],
        &[1],
        1,
        1,
    ),
    (
        "10.2 b",
        [5.871, -3.045, 7.442, -1.427, 1.76, -3.34, 1.906, -9.535],
        &[1],
        1,
        1,
    ),
    // Case 12: corners 1, 2, 3, 4 inside; faces x = 0 and y = 0 ambiguous.
    (
        "12.1.1 separated",
        [-7.238, 1.377, 3.01, 0.758, 2.564, -6.003, -1.566, -1.673],
        &[1, 1],
        2,
        1,
    ),
    (
        "12.1.1 joined",
        [-0.341, 0.56, 0.79, 1.105, 4.024, -0.454, -0.458, -2.51],
        &[1, 1],
        1,
        2,
    ),
    (
        "12.1.2 tunnel",
        [-1.272, 0.633, 1.243, 0.143, 1.959, -1.298, -0.129, -0.573],
        &[2],
        1,
        1,
    ),
    (
        "12.1.2 tunnel (outside)",
        [-1.75, 0.795, 1.25, 0.763, 0.591, -0.095, -1.439, -0.134],
        &[2],
        1,
        1,
    ),
    (
        "12.2 a",
        [-0.493, 0.626, 0.308, 0.248, 0.412, -0.102, -0.072, -0.517],
        &[1],
        1,
        1,
    ),
    (
        "12.2 b",
        [-8.783, 1.706, 14.568, 15.613, 2.232, -8.955, -2.856, -1.225],
        &[1],
        1,
        1,
    ),
    // Case 13: corners 0, 2, 5, 7 inside; all six faces ambiguous.
    (
        "13.1",
        [0.289, -0.771, 0.264, -0.28, -0.412, 0.069, -0.394, 0.083],
        &[1, 1, 1, 1],
        4,
        1,
    ),
    (
        "13.1 complement",
        [6.971, -2.313, 8.501, -1.201, -0.605, 3.001, -2.157, 2.28],
        &[1, 1, 1, 1],
        1,
        4,
    ),
    (
        "13.2 a",
        [1.9, -1.726, 5.334, -3.561, -1.155, 0.264, -5.34, 0.693],
        &[1, 1, 1],
        3,
        1,
    ),
    (
        "13.2 b",
        [0.515, -1.134, 1.454, -7.068, -13.484, 7.12, -2.269, 0.739],
        &[1, 1, 1],
        3,
        1,
    ),
    (
        "13.2 c",
        [11.48, -10.5, 0.571, -2.684, -4.061, 1.241, -10.563, 2.057],
        &[1, 1, 1],
        3,
        1,
    ),
    (
        "13.2 complement",
        [3.652, -2.25, 3.175, -2.337, -4.204, 1.877, -0.394, 6.184],
        &[1, 1, 1],
        1,
        3,
    ),
    (
        "13.3",
        [1.696, -2.54, 1.193, -0.106, -2.75, 1.089, -2.28, 2.236],
        &[1, 1, 1],
        2,
        2,
    ),
    (
        "13.4 / 13.5.1",
        [3.909, -4.561, 2.109, -4.583, -0.811, 7.385, -9.161, 7.766],
        &[1, 1, 1],
        2,
        2,
    ),
    (
        "13.5.2 tunnel",
        [1.261, -1.43, 1.767, -1.754, -0.055, 0.78, -1.706, 1.535],
        &[2, 1],
        1,
        2,
    ),
];

#[test]
fn mc33_configurations_match_the_trilinear_isosurface() {
    let mut failures = Vec::new();
    for (name, f, loops, nin, nout) in MC33 {
        let margin = relative_margin(f, 0.0);
        assert!(margin > 5e-3, "{name}: too close to degenerate ({margin})");
        let r =
            cell_reference(f, 48).unwrap_or_else(|e| panic!("{name}: reference inconsistent: {e}"));
        // The catalogue itself is right.
        assert_eq!(
            (
                &r.loops_per_component[..],
                r.inside_regions,
                r.outside_regions
            ),
            (*loops, *nin, *nout),
            "{name}: catalogue entry does not have the stated topology"
        );
        if let Err(e) = compare_cell(f, &r) {
            failures.push(format!("{name} f = {f:?}: {e}"));
        }
    }
    assert!(
        failures.is_empty(),
        "{} of {} configurations wrong:\n{}",
        failures.len(),
        MC33.len(),
        failures.join("\n")
    );
}

/// Every face decision and both interior outcomes appear in the catalogue
/// for the tunnel cases (a guard against the catalogue degrading).
#[test]
fn mc33_catalogue_covers_tunnels() {
    let tunnels = MC33.iter().filter(|e| e.2.contains(&2)).count();
    assert!(tunnels >= 9);
    let cases: std::collections::HashSet<u8> = MC33
        .iter()
        .map(|e| precisemc::mc::case_index(&e.1))
        .collect();
    for c in [65u8, 67, 26, 85, 30, 165] {
        assert!(cases.contains(&c), "case pattern {c} missing");
    }
    // Case 12's pattern has two adjacent ambiguous faces.
    let amb: Vec<usize> = (0..6).filter(|&k| face_is_ambiguous(30, k)).collect();
    assert_eq!(amb.len(), 2);
    assert_ne!(FACES[amb[0]].0, FACES[amb[1]].0);
}

#[test]
fn random_cells_match_the_trilinear_isosurface() {
    let mut rng = Rng::new(2024);
    let mut failures = Vec::new();
    let (mut compared, mut skipped) = (0, 0);
    let ambiguous: Vec<u8> = (1..=254u8)
        .filter(|&c| precisemc::tables::cube::NEEDS_TOPOLOGY_TEST[c as usize])
        .collect();
    for n in 0..170 {
        let mut f = [0.0; 8];
        if n % 2 == 0 {
            for v in f.iter_mut() {
                *v = rng.range(-1.0, 1.0);
            }
        } else {
            let case = ambiguous[rng.below(ambiguous.len() as u64) as usize];
            for (c, v) in f.iter_mut().enumerate() {
                let m = rng.log_uniform(0.1, 10.0);
                *v = if (case >> c) & 1 == 1 { m } else { -m };
            }
        }
        // 1e-2 rather than 1e-3: at 40 samples per edge a saddle 1e-3 from
        // the isovalue can make a neck thinner than the sampling.
        if relative_margin(&f, 0.0) < 1e-2 {
            skipped += 1;
            continue;
        }
        let r = match cell_reference(&f, 40) {
            Ok(r) => r,
            Err(_) => {
                skipped += 1;
                continue;
            }
        };
        compared += 1;
        if let Err(e) = compare_cell(&f, &r) {
            failures.push(format!("f = {f:?} decisions {:?}: {e}", face_decisions(&f)));
        }
    }
    assert!(
        compared >= 120,
        "only {compared} cells compared ({skipped} skipped)"
    );
    assert!(
        failures.is_empty(),
        "{} of {compared} cells wrong:\n{}",
        failures.len(),
        failures.join("\n")
    );
}

/// Random 6^3 volumes with a border of -1 and random values in [-1, 1]
/// inside (closed surfaces, ambiguous cells everywhere), plain and refined
/// with every rule.
#[test]
fn random_volumes_match_the_trilinear_isosurface() {
    let dims = [6, 6, 6];
    let mut failures = Vec::new();
    let mut compared = 0;
    // Refinement subdivides the Marching Cubes triangles (and meshes
    // stalled cells again on sub-cells, from level 3): the topology
    // must stay the trilinear isosurface's.
    let mut configs = vec![("MC".to_string(), mc_opts(Topology::Trilinear))];
    for rule in RULES {
        configs.push((
            format!("{rule:?} eps 0.01 L4"),
            refine_opts(Topology::Trilinear, rule, 0.01, 4),
        ));
    }
    // The cubic filters move points, never the topology.
    for reconstruction in [
        Reconstruction::CatmullRom,
        Reconstruction::BSplineInterpolating,
    ] {
        configs.push((
            format!("A1 {reconstruction:?} eps 0.01 L4"),
            Options {
                reconstruction,
                ..refine_opts(Topology::Trilinear, Rule::A1, 0.01, 4)
            },
        ));
    }
    let mut seed = 0;
    while compared < 20 && seed < 600 {
        seed += 1;
        let v = random_interior(dims, seed, -1.0, 1.0, -1.0);
        if volume_margin(&v, dims, 0.0) < 0.02 {
            continue;
        }
        compared += 1;
        let r = volume_reference(&v, dims, 0.0, 12);
        let want_components = r.inside_components + r.outside_components - 1;
        let want_euler = 2 * r.inside_euler;
        let volume = Volume::new(&v, dims_u64(dims));
        for (cfg, opts) in &configs {
            let mesh = extract(&volume, 0.0, opts).unwrap();
            let c = check_mesh(&mesh);
            if !c.is_closed_oriented_manifold()
                || c.components != want_components
                || c.euler != want_euler
            {
                failures.push(format!(
                    "seed {seed} {cfg}: mesh {} components, chi {} ({c:?}); reference {} components ({} inside, {} outside), chi {}",
                    c.components, c.euler, want_components, r.inside_components, r.outside_components, want_euler
                ));
            }
        }
    }
    assert!(compared >= 15, "only {compared} volumes compared");
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}
