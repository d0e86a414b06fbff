//! Classic rule sets (`Rules::Classic`): Catmull-Clark as OpenSubdiv's catmark at degree 3,
//! Doo-Sabin at degree 2. Parity with OpenSubdiv itself is tested in Python against bpy
//! (tests/test_classic_parity.py); these are the masks from their definitions. (A unit test of
//! the crate: it reads the per-level sharpness and rules and runs the Catmull-Clark step
//! directly.)

use super::common::{self, cage, grid, torus, Random};
use crate::scheme::catmark::{
    dart_limit_mask, fractional_weight, subdivide_edge_sharpness, vertex_rule, VertexRule,
};
use crate::scheme::{decrement, doo_sabin_weight};
use crate::step::catmark::{step_by, step_into};
use crate::{Boundary, Cage, Creasing, Options, OutputKind, Plan, Rules};

fn classic(degree: u32, levels: u32) -> Options {
    Options {
        degree,
        levels,
        rules: Rules::Classic,
        ..Options::default()
    }
}

type P = [f64; 3];

fn pts(flat: &[f64]) -> Vec<P> {
    flat.chunks(3).map(|c| [c[0], c[1], c[2]]).collect()
}

fn close(a: P, b: P) -> bool {
    (0..3).all(|k| (a[k] - b[k]).abs() < 1e-12)
}

fn comb(terms: &[(f64, P)]) -> P {
    let mut out = [0.0; 3];
    for (w, p) in terms {
        for k in 0..3 {
            out[k] += w * p[k];
        }
    }
    out
}

/// The fine vertex id of the edge point of cage edge `a-b` (level 0 of `plan`).
fn edge_point(plan: &Plan, a: u32, b: u32) -> usize {
    let l0 = &plan.levels()[0];
    let e = l0
        .edge_verts()
        .iter()
        .position(|&[x, y]| (x, y) == (a, b) || (x, y) == (b, a))
        .expect("an edge");
    l0.num_vertices + e
}

fn face_point(plan: &Plan, f: usize) -> usize {
    let l0 = &plan.levels()[0];
    l0.num_vertices + l0.num_edges() + f
}

fn random_points(n: usize, seed: u64) -> Vec<f64> {
    let mut r = Random(seed);
    (0..3 * n).map(|_| r.next()).collect()
}

#[test]
fn regular_regions_are_cubic_b_spline_refinement() {
    // A torus grid is regular everywhere: vertex points [1 6 1]/8 x [1 6 1]/8, edge points
    // [1 1]/2 x [1 6 1]/8, face points [1 1]/2 x [1 1]/2.
    let (m, n) = (6, 7);
    let cage = torus(m, n);
    let flat = random_points(m * n, 7);
    let p = pts(&flat);
    let plan = Plan::new(&cage, &classic(3, 1)).unwrap();
    let out = pts(&plan.evaluate(&flat, 3).unwrap());
    let id = |a: usize, b: usize| ((a + m) % m) * n + (b + n) % n;
    let b3 = [1.0 / 8.0, 6.0 / 8.0, 1.0 / 8.0];
    for a in 0..m {
        for b in 0..n {
            let mut terms = Vec::new();
            for (i, wi) in b3.iter().enumerate() {
                for (j, wj) in b3.iter().enumerate() {
                    terms.push((wi * wj, p[id(a + i + m - 1, b + j + n - 1)]));
                }
            }
            assert!(close(out[id(a, b)], comb(&terms)), "vertex ({a}, {b})");
            // Edge along a: between (a, b) and (a + 1, b).
            let mut terms = Vec::new();
            for (j, wj) in b3.iter().enumerate() {
                for i in 0..2 {
                    terms.push((0.5 * wj, p[id(a + i, b + j + n - 1)]));
                }
            }
            let e = edge_point(&plan, id(a, b) as u32, id(a + 1, b) as u32);
            assert!(close(out[e], comb(&terms)), "edge ({a}, {b})");
        }
    }
    // The same refinement as the averaging scheme's degree 3 on a regular mesh.
    let averaging = Plan::new(
        &cage,
        &Options {
            degree: 3,
            levels: 2,
            ..Options::default()
        },
    )
    .unwrap()
    .evaluate(&flat, 3)
    .unwrap();
    let two = Plan::new(&cage, &classic(3, 2))
        .unwrap()
        .evaluate(&flat, 3)
        .unwrap();
    assert!(averaging
        .iter()
        .zip(&two)
        .all(|(a, b)| (a - b).abs() < 1e-12));
}

/// A closed bipyramid over a k-gon: apex 0 and 1 of valence k, ring 2..k+2.
fn bipyramid(k: usize) -> (Cage, Vec<f64>) {
    let mut faces = Vec::new();
    for i in 0..k {
        let (a, b) = (2 + i, 2 + (i + 1) % k);
        faces.push(vec![0, a, b]);
        faces.push(vec![1, b, a]);
    }
    let mut flat = vec![0.1, -0.2, 1.3, 0.2, 0.1, -1.1];
    for i in 0..k {
        let t = std::f64::consts::TAU * i as f64 / k as f64;
        flat.extend([t.cos() * (1.0 + 0.1 * i as f64), t.sin(), 0.05 * i as f64]);
    }
    (cage(k + 2, &faces), flat)
}

#[test]
fn valence_k_vertex_rule() {
    for k in 3..=12 {
        let (cage, flat) = bipyramid(k);
        let p = pts(&flat);
        let plan = Plan::new(&cage, &classic(3, 1)).unwrap();
        let out = pts(&plan.evaluate(&flat, 3).unwrap());
        let kf = k as f64;
        let mut terms = vec![((kf - 2.0) / kf, p[0])];
        for i in 0..k {
            let (a, b) = (2 + i, 2 + (i + 1) % k);
            terms.push((1.0 / (kf * kf), p[a]));
            let centroid = comb(&[(1.0 / 3.0, p[0]), (1.0 / 3.0, p[a]), (1.0 / 3.0, p[b])]);
            terms.push((1.0 / (kf * kf), centroid));
        }
        assert!(close(out[0], comb(&terms)), "valence {k}");
        // Face points are centroids, edge points the mean of ends and face points.
        let f0 = comb(&[(1.0 / 3.0, p[0]), (1.0 / 3.0, p[2]), (1.0 / 3.0, p[3])]);
        assert!(close(out[face_point(&plan, 0)], f0));
        let e = edge_point(&plan, 0, 2);
        let f_last = comb(&[(1.0 / 3.0, p[0]), (1.0 / 3.0, p[k + 1]), (1.0 / 3.0, p[2])]);
        let want = comb(&[(0.25, p[0]), (0.25, p[2]), (0.25, f0), (0.25, f_last)]);
        assert!(close(out[e], want), "edge point, valence {k}");
    }
}

#[test]
fn doo_sabin_weights() {
    let w: Vec<f64> = (0..4).map(|i| doo_sabin_weight(i, 4)).collect();
    let want = [9.0 / 16.0, 3.0 / 16.0, 1.0 / 16.0, 3.0 / 16.0];
    assert!(w.iter().zip(want).all(|(a, b)| (a - b).abs() < 1e-15));
    for k in 3..=20 {
        let sum: f64 = (0..k).map(|i| doo_sabin_weight(i, k)).sum();
        assert!((sum - 1.0).abs() < 1e-14, "k = {k}");
    }
    // A closed pentagonal prism, one level, true dual output: the face of corner c of the cage
    // is the Doo-Sabin point of that corner.
    let k = 5;
    let mut faces = vec![(0..k).rev().collect::<Vec<_>>(), (k..2 * k).collect()];
    for i in 0..k {
        let j = (i + 1) % k;
        faces.push(vec![i, j, k + j, k + i]);
    }
    let cage = cage(2 * k, &faces);
    let flat = random_points(2 * k, 3);
    let p = pts(&flat);
    let plan = Plan::new(
        &cage,
        &Options {
            output: OutputKind::Dual,
            ..classic(2, 1)
        },
    )
    .unwrap();
    let out = pts(&plan.evaluate(&flat, 3).unwrap());
    let l0 = &plan.levels()[0];
    for (c, &child) in out[..l0.num_corners()].iter().enumerate() {
        let f = l0.face_of(c);
        let r = l0.face_corners(f);
        let n = r.len();
        let terms: Vec<(f64, P)> = (0..n)
            .map(|i| {
                let at = r.start + (c - r.start + i) % n;
                (doo_sabin_weight(i, n), p[l0.corner_verts[at] as usize])
            })
            .collect();
        assert!(close(child, comb(&terms)), "corner {c}");
    }
    // Second level: dual data, the faces around each vertex (valence 3 everywhere).
    let plan2 = Plan::new(
        &cage,
        &Options {
            output: OutputKind::Dual,
            ..classic(2, 2)
        },
    )
    .unwrap();
    let out2 = pts(&plan2.evaluate(&flat, 3).unwrap());
    let l1 = &plan2.levels()[1];
    for (c, &child) in out2[..l1.num_corners()].iter().enumerate() {
        let v = l1.corner_verts[c] as usize;
        let ring = l1.corners_of_vertex(v);
        let k = ring.len();
        // Walk around v from c as in the definition (weights are symmetric).
        let mut at = c;
        let mut terms = Vec::new();
        for i in 0..k {
            terms.push((doo_sabin_weight(i, k), out[l1.face_of(at)]));
            let prev = l1.prev(at);
            let [x, y] = l1.edge_corners()[l1.corner_edges()[prev] as usize];
            at = if x as usize == prev { y } else { x } as usize;
        }
        assert!(close(child, comb(&terms)), "level 2 corner {c}");
    }
    // On a regular mesh classic degree 2 is biquadratic, as the averaging scheme of degree 2.
    let t = torus(5, 6);
    let tf = random_points(30, 5);
    let a = Plan::new(
        &t,
        &Options {
            degree: 2,
            levels: 2,
            ..Options::default()
        },
    )
    .unwrap()
    .evaluate(&tf, 3)
    .unwrap();
    let b = Plan::new(&t, &classic(2, 2))
        .unwrap()
        .evaluate(&tf, 3)
        .unwrap();
    assert!(a.iter().zip(&b).all(|(x, y)| (x - y).abs() < 1e-12));
}

#[test]
fn crease_and_corner_masks() {
    // Open 4 x 4 grid: boundary vertices 3/4 v + 1/8 neighbours, boundary edge points midpoints,
    // grid corners are creases (edge only) or interpolated (edge and corner).
    let (g, mut flat) = common::grid(4, 4);
    let mut r = Random(11);
    for z in flat.iter_mut().skip(2).step_by(3) {
        *z = r.next();
    }
    let p = pts(&flat);
    let id = |a: usize, b: usize| a * 5 + b;
    for boundary in [Boundary::EdgeOnly, Boundary::EdgeAndCorner] {
        let plan = Plan::new(
            &g,
            &Options {
                boundary,
                ..classic(3, 1)
            },
        )
        .unwrap();
        let out = pts(&plan.evaluate(&flat, 3).unwrap());
        let v = id(0, 2);
        let want = comb(&[(0.75, p[v]), (0.125, p[id(0, 1)]), (0.125, p[id(0, 3)])]);
        assert!(close(out[v], want));
        let e = edge_point(&plan, id(0, 1) as u32, id(0, 2) as u32);
        assert!(close(
            out[e],
            comb(&[(0.5, p[id(0, 1)]), (0.5, p[id(0, 2)])])
        ));
        let corner = id(0, 0);
        let want = match boundary {
            Boundary::EdgeOnly | Boundary::None => comb(&[
                (0.75, p[corner]),
                (0.125, p[id(0, 1)]),
                (0.125, p[id(1, 0)]),
            ]),
            Boundary::EdgeAndCorner => p[corner],
        };
        assert!(close(out[corner], want), "{boundary:?}");
    }
    // A cube with every edge infinitely sharp: vertices are corners (three sharp edges), edge
    // points midpoints, faces bilinear; an interior crease through a vertex uses 3/4, 1/8.
    let faces = [
        vec![0, 3, 2, 1],
        vec![4, 5, 6, 7],
        vec![0, 1, 5, 4],
        vec![1, 2, 6, 5],
        vec![2, 3, 7, 6],
        vec![3, 0, 4, 7],
    ];
    let cube = cage(8, &faces);
    let flat: Vec<f64> = (0..8)
        .flat_map(|v| [(v & 1) as f64, ((v >> 1) & 1) as f64, (v >> 2) as f64])
        .map(|x| x + 0.01)
        .collect();
    let flat: Vec<f64> = flat
        .iter()
        .enumerate()
        .map(|(i, x)| x + 0.1 * (i as f64 * 0.37).sin())
        .collect();
    let p = pts(&flat);
    let mut creases = Vec::new();
    for f in &faces {
        for i in 0..4 {
            creases.push((f[i] as i64, f[(i + 1) % 4] as i64, 10.0f32));
        }
    }
    let sharp = cube.clone().with_creases(&creases).unwrap();
    let plan = Plan::new(&sharp, &classic(3, 1)).unwrap();
    let out = pts(&plan.evaluate(&flat, 3).unwrap());
    for v in 0..8 {
        assert!(close(out[v], p[v]), "corner {v}");
    }
    let e = edge_point(&plan, 0, 1);
    assert!(close(out[e], comb(&[(0.5, p[0]), (0.5, p[1])])));
    // One crease loop 0-1-2-3 (the bottom face's boundary): crease vertex rule at its vertices.
    let ring = cube
        .clone()
        .with_creases(&[(0, 1, 10.0), (1, 2, 10.0), (2, 3, 10.0), (3, 0, 10.0)])
        .unwrap();
    let plan = Plan::new(&ring, &classic(3, 1)).unwrap();
    assert_eq!(
        plan.refinement().sharpness(0).unwrap().rule(1),
        VertexRule::Crease
    );
    let out = pts(&plan.evaluate(&flat, 3).unwrap());
    assert!(close(
        out[1],
        comb(&[(0.75, p[1]), (0.125, p[0]), (0.125, p[2])])
    ));
    // A dart (one sharp edge) uses the smooth rules; its other end too.
    let dart = cube.clone().with_creases(&[(0, 1, 10.0)]).unwrap();
    let plan = Plan::new(&dart, &classic(3, 1)).unwrap();
    assert_eq!(
        plan.refinement().sharpness(0).unwrap().rule(0),
        VertexRule::Dart
    );
    let smooth = Plan::new(&cube, &classic(3, 1))
        .unwrap()
        .evaluate(&flat, 3)
        .unwrap();
    let darted = pts(&plan.evaluate(&flat, 3).unwrap());
    assert!(close(darted[0], pts(&smooth)[0]));
    // A sharp vertex is a corner.
    let pinned = cube.clone().with_corners(&[(5, 10.0)]).unwrap();
    let out = pts(&Plan::new(&pinned, &classic(3, 1))
        .unwrap()
        .evaluate(&flat, 3)
        .unwrap());
    assert!(close(out[5], p[5]));
}

#[test]
fn semi_sharp_decrement() {
    assert_eq!(decrement(2.5), 1.5);
    assert_eq!(decrement(1.0), 0.0);
    assert_eq!(decrement(0.5), 0.0);
    assert_eq!(decrement(12.0), 10.0);
    assert_eq!(vertex_rule(0.0, 0), VertexRule::Smooth);
    assert_eq!(vertex_rule(0.0, 1), VertexRule::Dart);
    assert_eq!(vertex_rule(0.0, 2), VertexRule::Crease);
    assert_eq!(vertex_rule(0.0, 3), VertexRule::Corner);
    assert_eq!(vertex_rule(0.3, 0), VertexRule::Corner);
    // Chaikin: 3/4 own + 1/4 mean of the other semi-sharp edges, minus one.
    let s = subdivide_edge_sharpness(3.0, &[3.0, 1.0, 0.0, 10.0], Creasing::Chaikin);
    assert!((s - (0.75 * 3.0 + 0.25 * 1.0 - 1.0)).abs() < 1e-6);
    assert_eq!(
        subdivide_edge_sharpness(3.0, &[3.0, 1.0], Creasing::Uniform),
        2.0
    );
    assert_eq!(
        subdivide_edge_sharpness(3.0, &[3.0, 0.0], Creasing::Chaikin),
        2.0
    );
    // Fractional weight: mean of the sharpness of the edges that become smooth, at most 1.
    let w = fractional_weight(
        0.0,
        0.0,
        &[0.5, 0.5, 0.0],
        &[0.0, 0.0, 0.0],
        Creasing::Uniform,
    );
    assert!((w - 0.5).abs() < 1e-7);
    let w = fractional_weight(0.3, 0.0, &[0.0; 4], &[0.0; 4], Creasing::Uniform);
    assert!((w - 0.3).abs() < 1e-7);

    // A crease of sharpness 2.3 across a torus: 2.3, 1.3, 0.3, then smooth.
    let (m, n) = (6, 6);
    let id = |a: usize, b: usize| (a % m) * n + (b % n);
    let creases: Vec<(i64, i64, f32)> = (0..m)
        .map(|a| (id(a, 0) as i64, id(a + 1, 0) as i64, 2.3f32))
        .collect();
    let t = torus(m, n).with_creases(&creases).unwrap();
    let plan = Plan::new(&t, &classic(3, 4)).unwrap();
    let catmark = |j| plan.refinement().sharpness(j).unwrap();
    let e0 = plan.levels()[0]
        .edge_verts()
        .iter()
        .position(|&[a, b]| (a, b) == (0, id(1, 0) as u32))
        .unwrap();
    for (j, want) in [2.3f32, 1.3, 0.3, 0.0].into_iter().enumerate() {
        let got = catmark(j).edge(e0 << j);
        assert!((got - want).abs() < 1e-5, "level {j}: {got}");
    }
    assert_eq!(catmark(0).rule(0), VertexRule::Crease);
    assert_eq!(catmark(3).rule(0), VertexRule::Smooth);
    // Sharpness 0.5: edge points blend the crease and smooth masks half and half; vertex
    // points half crease, half smooth.
    let creases: Vec<(i64, i64, f32)> = (0..m)
        .map(|a| (id(a, 0) as i64, id(a + 1, 0) as i64, 0.5f32))
        .collect();
    let half = torus(m, n).with_creases(&creases).unwrap();
    let flat = random_points(m * n, 9);
    let soft = Plan::new(&half, &classic(3, 1)).unwrap();
    let smooth = pts(&Plan::new(&torus(m, n), &classic(3, 1))
        .unwrap()
        .evaluate(&flat, 3)
        .unwrap());
    let sharp_cage = torus(m, n)
        .with_creases(
            &creases
                .iter()
                .map(|&(a, b, _)| (a, b, 10.0))
                .collect::<Vec<_>>(),
        )
        .unwrap();
    let sharp = pts(&Plan::new(&sharp_cage, &classic(3, 1))
        .unwrap()
        .evaluate(&flat, 3)
        .unwrap());
    let out = pts(&soft.evaluate(&flat, 3).unwrap());
    for w in [0, edge_point(&soft, 0, id(1, 0) as u32)] {
        let want = comb(&[(0.5, smooth[w]), (0.5, sharp[w])]);
        assert!(close(out[w], want), "vertex {w}");
    }
}

#[test]
fn limit_positions() {
    // Regular torus: [1 4 1] x [1 4 1] / 36 at level 1 vertices.
    let (m, n) = (5, 6);
    let t = torus(m, n);
    let flat = random_points(m * n, 21);
    let plan = Plan::new(&t, &classic(3, 1)).unwrap();
    let fine = pts(&plan.evaluate(&flat, 3).unwrap());
    let limit = pts(&plan.limit_positions(&flat, 3).unwrap());
    let l1 = &plan.levels()[1];
    for v in 0..l1.num_vertices {
        let mut terms = vec![(16.0 / 36.0, fine[v])];
        for &c in l1.corners_of_vertex(v) {
            let nx = l1.next(c as usize);
            terms.push((4.0 / 36.0, fine[l1.corner_verts[nx] as usize]));
            terms.push((1.0 / 36.0, fine[l1.corner_verts[l1.next(nx)] as usize]));
        }
        assert!(close(limit[v], comb(&terms)));
    }
    // The limit is a fixed point of refinement: level 1 and level 3 agree at cage vertices.
    let (b, bf) = bipyramid(7);
    let one = Plan::new(&b, &classic(3, 1))
        .unwrap()
        .limit_positions(&bf, 3)
        .unwrap();
    let three = Plan::new(&b, &classic(3, 3))
        .unwrap()
        .limit_positions(&bf, 3)
        .unwrap();
    for i in 0..3 * 9 {
        assert!((one[i] - three[i]).abs() < 1e-12);
    }
    // An infinitely sharp dart (one sharp edge into a bipyramid apex): its limit mask is the
    // left eigenvector of the 1-ring matrix, so again a fixed point of refinement, and it differs
    // from the smooth mask.
    let dart = b.clone().with_creases(&[(0, 2, 10.0)]).unwrap();
    let one = Plan::new(&dart, &classic(3, 1))
        .unwrap()
        .limit_positions(&bf, 3)
        .unwrap();
    let three = Plan::new(&dart, &classic(3, 3))
        .unwrap()
        .limit_positions(&bf, 3)
        .unwrap();
    for i in 0..3 * 9 {
        assert!((one[i] - three[i]).abs() < 1e-12, "{i}");
    }
    let mask = dart_limit_mask(7, 0);
    assert!((mask.iter().sum::<f64>() - 1.0).abs() < 1e-14);
    let f = 1.0 / (7.0 * 12.0);
    assert!((mask[0] - (1.0 - 35.0 * f)).abs() > 1e-3);
    let averaging = Plan::new(
        &b,
        &Options {
            degree: 3,
            levels: 1,
            ..Options::default()
        },
    )
    .unwrap();
    // The averaging scheme has its own limit (crate::limit), another surface at valence 7.
    let ours = averaging.limit_positions(&bf, 3).unwrap();
    let theirs = Plan::new(&b, &classic(3, 1))
        .unwrap()
        .limit_positions(&bf, 3)
        .unwrap();
    assert!(ours.iter().zip(&theirs).any(|(x, y)| (x - y).abs() > 1e-6));
    assert!(Plan::new(&b, &classic(4, 1)).is_err());
}

#[test]
fn doo_sabin_keeps_the_averaging_boundary_and_outputs_work() {
    // An open disk around a valence-5 vertex: classic degree 2 replaces the faces around
    // interior vertices only; at boundary vertices (curve vertices) it keeps the averaging
    // scheme's values, so the boundary curve is the same.
    let (disk, mut flat) = common::polar_grid(5, 3);
    let mut r = Random(5);
    for z in flat.iter_mut().skip(2).step_by(3) {
        *z = 0.3 * r.next();
    }
    // The first step starts from primal data (the cage's quads, where the Doo-Sabin weights are
    // the averaging ones); the second is dual, around the vertices of M_1.
    let options = |rules| Options {
        degree: 2,
        levels: 2,
        output: OutputKind::Dual,
        rules,
        ..Options::default()
    };
    let a = Plan::new(&disk, &options(Rules::Averaging)).unwrap();
    let b = Plan::new(&disk, &options(Rules::Classic)).unwrap();
    let (pa, pb) = (
        pts(&a.evaluate(&flat, 3).unwrap()),
        pts(&b.evaluate(&flat, 3).unwrap()),
    );
    assert_eq!(pa.len(), pb.len());
    let l0 = &a.levels()[1];
    let step = &a.curve_networks()[1];
    let on_curve = |v: u32| step.curve_vertices().any(|x| x == v);
    let mut differ = 0;
    for c in 0..l0.num_corners() {
        if on_curve(l0.corner_verts[c]) {
            assert!(close(pa[c], pb[c]), "corner {c} at a boundary vertex");
        } else if !close(pa[c], pb[c]) {
            differ += 1;
        }
    }
    // Only the five corners at the valence-5 vertex change.
    assert_eq!(differ, 5);
    // The boundary points of the dual mesh are the same.
    assert!(pa[l0.num_corners()..]
        .iter()
        .zip(&pb[l0.num_corners()..])
        .all(|(x, y)| close(*x, *y)));
    // Classic degree 3 with the dual output and degree 2 with the drawing mesh run too.
    for (degree, output) in [(3, OutputKind::Dual), (2, OutputKind::Primal)] {
        let plan = Plan::new(
            &disk,
            &Options {
                degree,
                levels: 2,
                output,
                rules: Rules::Classic,
                ..Options::default()
            },
        )
        .unwrap();
        let out = plan.evaluate(&flat, 3).unwrap();
        assert_eq!(out.len(), 3 * plan.num_output_vertices());
        assert!(out.iter().all(|x| x.is_finite()));
    }
}

#[test]
fn step_into_reuses_a_dirty_buffer_and_matches_step() {
    // A bipyramid (triangles, valence 4 and k) and a torus with a crease, two levels each:
    // `step_into` on a buffer holding garbage (and larger than needed) equals `step` bitwise.
    let (bi, bi_points) = bipyramid(5);
    let creased = torus(4, 5)
        .with_creases(&[(0, 1, 2.5), (1, 2, 10.0)])
        .unwrap();
    let torus_points = random_points(20, 7);
    for (cage, points) in [(bi, bi_points), (creased, torus_points)] {
        let plan = Plan::new(&cage, &classic(3, 2)).unwrap();
        let levels = plan.levels();
        let creasing = Creasing::Uniform;
        let mut values: Vec<P> = pts(&points);
        let mut buffer: Vec<P> = vec![[f64::NAN; 3]; 4 * levels[2].num_vertices];
        for j in 0..2 {
            let step = plan.refinement().step(j);
            let mut expected = Vec::new();
            step_into(&step, creasing, &values, &mut expected).unwrap();
            step_into(&step, creasing, &values, &mut buffer).unwrap();
            assert_eq!(buffer.len(), levels[j + 1].num_vertices);
            let bits = |v: &[P]| v.iter().flatten().map(|x| x.to_bits()).collect::<Vec<_>>();
            assert_eq!(bits(&buffer), bits(&expected));
            values = expected;
        }
    }
}

#[test]
fn fused_smooth_points_are_the_rules_bit_for_bit() {
    // A plan's smooth points of a quad level by the fused sums (each from the net of the face
    // that owns it) equal, bit for bit, every point by its rule over the coarse level, wherever
    // the rules are smooth, creased, semi-sharp, blended or at corners; and each smooth point
    // of a quad level equals the classic mask written from its definition (face points the
    // centroids) to rounding. At irregular valences (the bipyramid's apexes and its triangles'
    // children) and on the triangles both sides take the masks.
    let (bi, bi_points) = bipyramid(5);
    let creased = torus(4, 5)
        .with_creases(&[(0, 1, 2.5), (1, 2, 10.0), (6, 7, 0.5)])
        .unwrap()
        .with_corners(&[(12, 1.5)])
        .unwrap();
    let (open, open_points) = grid(3, 4);
    let open = open.with_creases(&[(6, 7, 1.25)]).unwrap();
    let mut r = Random(3);
    let open_points: Vec<f64> = open_points.iter().map(|x| x + 0.3 * r.next()).collect();
    let cases = [
        (bi, bi_points, Boundary::EdgeOnly),
        (creased, random_points(20, 7), Boundary::EdgeOnly),
        (open.clone(), open_points.clone(), Boundary::EdgeOnly),
        (open, open_points, Boundary::EdgeAndCorner),
    ];
    let bits = |v: &[P]| v.iter().flatten().map(|x| x.to_bits()).collect::<Vec<_>>();
    let (mut fused_steps, mut checked) = (0, 0);
    for (cage, points, boundary) in cases {
        for creasing in [Creasing::Uniform, Creasing::Chaikin] {
            let options = Options {
                boundary,
                creasing,
                ..classic(3, 3)
            };
            let plan = Plan::new(&cage, &options).unwrap();
            let mut values: Vec<P> = pts(&points);
            for j in 0..3 {
                let step = plan.refinement().step(j);
                let (mut by_rules, mut fused) = (Vec::new(), Vec::new());
                step_by(&step, creasing, &values, &mut by_rules, false).unwrap();
                step_by(&step, creasing, &values, &mut fused, true).unwrap();
                assert_eq!(bits(&fused), bits(&by_rules), "step {j}");
                assert_eq!(step.smooth_points.is_some(), step.coarse.all_quads());
                fused_steps += step.smooth_points.is_some() as usize;
                if step.coarse.all_quads() {
                    checked += smooth_points_are_the_masks(&plan, j, &values, &fused);
                }
                values = fused;
            }
        }
    }
    // Levels 1 and 2 of every case, and the torus's and grids' cages.
    assert_eq!(fused_steps, 2 * (4 * 2 + 3));
    assert!(checked > 1000, "{checked} smooth points checked");
}

/// Checks each smooth point of step `j` of `plan` (a quad level: every face point, the edge
/// points of interior edges of sharpness 0, the vertex points of smooth vertices of valence 4)
/// in `fine` against Catmull-Clark's masks from their definitions over `coarse` (within 1e-12
/// of the data's scale); returns how many were checked.
fn smooth_points_are_the_masks(plan: &Plan, j: usize, coarse: &[P], fine: &[P]) -> usize {
    let level = &plan.levels()[j];
    let sharpness = plan.refinement().sharpness(j).unwrap();
    let (nv, ne) = (level.num_vertices, level.num_edges());
    let scale = fine.iter().flatten().fold(1.0f64, |m, x| m.max(x.abs()));
    let centroid = |f: usize| {
        let corners: Vec<(f64, P)> = level
            .face_corners(f)
            .map(|c| (0.25, coarse[level.corner_verts[c] as usize]))
            .collect();
        comb(&corners)
    };
    let near = |a: P, b: P| (0..3).all(|k| (a[k] - b[k]).abs() <= 1e-12 * scale);
    let mut checked = 0;
    for f in 0..level.num_faces() {
        assert!(near(fine[nv + ne + f], centroid(f)), "face {f}");
        checked += 1;
    }
    for (e, &[c0, c1]) in level.edge_corners().iter().enumerate() {
        if sharpness.edge(e) > 0.0 || c1 == u32::MAX {
            continue;
        }
        let [a, b] = level.edge_verts()[e].map(|v| coarse[v as usize]);
        let [f0, f1] = [c0, c1].map(|c| centroid(level.face_of(c as usize)));
        let mask = comb(&[(0.25, a), (0.25, b), (0.25, f0), (0.25, f1)]);
        assert!(near(fine[nv + e], mask), "edge {e}");
        checked += 1;
    }
    for v in 0..nv {
        let corners = level.corners_of_vertex(v);
        if !sharpness.rule(v).is_smooth() || corners.len() != 4 {
            continue;
        }
        // (k - 2) / k v + 1 / k^2 (sum of edge neighbours + sum of face points), k = 4.
        let mut terms = vec![(0.5, coarse[v])];
        for &c in corners {
            let neighbour = level.corner_verts[level.next(c as usize)] as usize;
            terms.push((1.0 / 16.0, coarse[neighbour]));
            terms.push((1.0 / 16.0, centroid(level.face_of(c as usize))));
        }
        assert!(near(fine[v], comb(&terms)), "vertex {v}");
        checked += 1;
    }
    checked
}

#[test]
fn the_estimate_counts_the_smooth_points() {
    // The memory estimate of a classic plan counts the smooth points' tables of every step
    // from a quad level (the torus's cage and every later level).
    let cage = torus(6, 8);
    for levels in [1, 2, 3] {
        let options = classic(3, levels);
        let plan = Plan::new(&cage, &options).unwrap();
        let tables: usize = (0..levels as usize)
            .filter_map(|j| plan.refinement().step(j).smooth_points)
            .map(|points| points.bytes())
            .sum();
        assert!(tables > 0);
        let bilinear = Options {
            degree: 1,
            ..options
        };
        let more = crate::estimate(&cage, &options).unwrap().bytes
            - crate::estimate(&cage, &bilinear).unwrap().bytes;
        assert!(
            more >= tables as u64,
            "{levels} levels: {more} bytes estimated for {tables}"
        );
    }
}
