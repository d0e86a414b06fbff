//! The dual grid of a drawing step of degree 2 or 4: per coarse vertex inside a grid, its
//! corners as a cycle (the faces of its dual face), its net of sixteen coarse faces, and the
//! drawing points it owns ([`Fused::drawing`]).
use std::mem::MaybeUninit;

use rayon::prelude::*;

use super::super::regular::{after, Tables as CornerTables};
use super::{ClosureIds, Fused, EDGE_BIT, FACE_BIT, NET};
use crate::error::{Error, Result};
use crate::memory;
use crate::parallel::CHUNK;
use crate::topology::Level;

/// The frame point of the `j`-th coarse face the walk of a dual face (a coarse vertex, whose
/// corner `k` is the coarse face at [`super::CORNERS`]`[k]`) names from its corner `k`: the
/// corner's face, the face across its edge after the coarse vertex's corner (`A`), the face
/// across the edge after that (`B`), and the face across `A`'s edge before the corner it shares
/// with `B`'s face (the diagonal), each pointing away from the dual face. For corner 0 these are
/// `(0, 0)`, `(0, -1)`, `(-1, 0)` and `(-1, -1)`: the coarse vertex's corner in face `(0, 0)`
/// has its outgoing edge towards face `(1, 0)` (the next corner of the dual face) and its
/// incoming edge towards `(0, 1)`. Over the four corners, the sixteen faces of the net.
pub(super) const fn walked_dual(k: usize, j: usize) -> (i32, i32) {
    let cells = [(0, 0), (0, -1), (-1, 0), (-1, -1)];
    turned(cells[j].0, cells[j].1, k)
}

/// A frame point turned `k` quarter turns about the centre of the face `(0, 0)..(1, 1)`,
/// which takes corner `k` of [`super::CORNERS`] to corner `k + 1`.
const fn turned(x: i32, y: i32, k: usize) -> (i32, i32) {
    match k % 4 {
        0 => (x, y),
        _ => {
            let (x, y) = turned(x, y, k - 1);
            (1 - y, x)
        }
    }
}

impl Fused {
    /// The fused drawing points of the step of `degree` (2 or 4) from dual data on `coarse`
    /// whose kernel writes the children of `masks`, with the level's corner tables as the
    /// regular windows' walk reads them: the fine vertices as one more dual -> primal average
    /// of those children would make them, straight from the coarse faces' data where the
    /// kernel makes the four children around a point. One more average of dual input gives the
    /// 1-D masks of the next odd degree with the roles of vertex and midpoint swapped, so the
    /// sums are that degree's over the dual grid (coarse faces as its vertices, coarse vertices
    /// as its faces); `None` when no point is fused.
    pub(in crate::step) fn drawing(
        coarse: &Level,
        degree: u32,
        masks: &[u8],
        corners: CornerTables,
    ) -> Result<Option<Fused>> {
        let ids = ClosureIds::of(coarse)?;
        let [nv, ne, nf] = ids.sizes();
        if masks.len() != nf || !matches!(degree, 2 | 4) {
            return Err(Error::Internal(
                "fused drawing points: masks not the level's, or no sums for the degree".into(),
            ));
        }
        let grid = DualGrid::of(coarse, masks, corners)?;
        // Each owned bit names its point ([`ClosureIds::fine_vertex`]): a vertex's own point,
        // the edge of a corner whose outgoing edge it is, the face of a corner of the face.
        ids.with_cycles(&grid.cycles)?;
        let rest = grid.rest;
        if rest.len() == nv + ne + nf {
            return Ok(None);
        }
        Ok(Some(Fused {
            degree: degree + 1,
            owned: grid.owned,
            nets: grid.nets,
            cycles: grid.cycles,
            rest,
            ids: [nv, ne, nf],
            whole: true,
        }))
    }
}

/// The net of the dual face of a coarse vertex with corners `cycle` (a cycle of the level's
/// corners, [`DualGrid::cycles`]) in the dual walk's order ([`walked_dual`]), from the walk's
/// corner tables; 0 for the dead face. What [`super::wide::dual_net`] does in vectors.
fn dual_net(corners: CornerTables, cycle: [u32; 4], net: &mut [MaybeUninit<u32>; NET]) {
    let dead = (corners.corner_tables().0.len() - 4) as u32;
    let face = |c: u32| if c < dead { c >> 2 } else { 0 };
    for (k, &c) in cycle.iter().enumerate() {
        // Corners of the level (the cycle's are below `dead`), or of the dead face where a
        // twin is missing: all within the walk's tables.
        let a = corners.twin(after(c, 1));
        let b = corners.twin(after(c, 2));
        let d = corners.twin(after(a, 3));
        net[k].write(c >> 2);
        net[4 + k].write(face(a));
        net[8 + k].write(face(b));
        net[12 + k].write(face(d));
    }
}

/// The dual grid of a drawing step on `coarse`, whose kernel makes the children of `masks`.
struct DualGrid {
    /// Per vertex that can be inside a grid, its corners in the order of its dual face's
    /// corners: from its first corner in the level's vertex table, each the corner at the
    /// vertex in the face across the previous one's outgoing edge (`after(twin(c), 1)`),
    /// checked to close after four, every one a corner of the level; four zeros (a corner of
    /// the level, read by no sum) for any other vertex.
    cycles: Vec<u32>,
    /// Per vertex, its net of [`NET`] coarse faces in the dual walk's order ([`walked_dual`]; 0
    /// where the walk leaves the level, and for a vertex without a cycle: read by no sum).
    nets: Vec<u32>,
    /// Per vertex, the points it owns ([`Fused::owned`]): a fine vertex is fused when the kernel
    /// makes the four children around it, and its owner is a vertex with a cycle: a vertex's
    /// own point, an edge's at the vertex of the edge's first corner, a face's at the vertex
    /// of its corner 0 (else the point is left to the average).
    owned: Vec<u16>,
    /// The fine vertices no vertex owns, increasing.
    rest: Vec<u32>,
}

impl DualGrid {
    /// The dual grid: the cycles, nets and own points in one parallel pass over the vertices
    /// (the level's corner tables as the regular windows' walk reads them), the edge and face
    /// points' owners in one pass over the edges and one over the faces.
    fn of(coarse: &Level, masks: &[u8], corners: CornerTables) -> Result<DualGrid> {
        let (nv, ne, nf) = (coarse.num_vertices, coarse.num_edges(), coarse.num_faces());
        let dead = 4 * nf as u32;
        let (offsets, vertex_corners) = coarse.vertex_corner_table();
        let (corner_verts, edge_corners) = (&coarse.corner_verts, coarse.edge_corners());
        let corner_edges = coarse.corner_edges();
        let fits = offsets.len() == nv + 1
            && corners.corner_tables().0.len() == 4 * nf + 4
            && masks.len() == nf
            && corner_verts.len() == 4 * nf
            && corner_edges.len() == 4 * nf
            && edge_corners.len() == ne;
        if !fits {
            return Err(Error::Internal(
                "fused drawing points: a level's tables out of range".into(),
            ));
        }
        // The corners of vertex `v` as a cycle.
        let cycle = |v: usize| -> Option<[u32; 4]> {
            let first = *vertex_corners.get(*offsets.get(v)? as usize)?;
            if first >= dead || !corners.grid(v as u32) {
                return None;
            }
            let mut cycle = [first; 4];
            for k in 0..4 {
                // Below `dead`: the vertex's corners have twins (`grid`).
                let next = after(corners.twin(cycle[k]), 1);
                match k {
                    3 if next != first => return None,
                    3 => {}
                    _ if corners.vertex(next) != v as u32 => return None,
                    _ => cycle[k + 1] = next,
                }
            }
            Some(cycle)
        };
        // Whether the kernel makes the child at corner `c` (below `dead`).
        let child = |c: u32| masks[(c >> 2) as usize] & (1 << (c & 3)) != 0;
        let mut cycles: Vec<u32> = memory::with_capacity(4 * nv)?;
        let mut nets: Vec<u32> = memory::with_capacity(NET * nv)?;
        let mut owned: Vec<u16> = memory::with_capacity(nv)?;
        (cycles.spare_capacity_mut()[..4 * nv].par_chunks_mut(4 * CHUNK))
            .zip(nets.spare_capacity_mut()[..NET * nv].par_chunks_mut(NET * CHUNK))
            .zip(owned.spare_capacity_mut()[..nv].par_chunks_mut(CHUNK))
            .enumerate()
            .for_each(|(chunk, ((cycles, nets), owned))| {
                let rows = (cycles.chunks_exact_mut(4).zip(nets.chunks_exact_mut(NET))).zip(owned);
                for (i, ((out, net), bits)) in rows.enumerate() {
                    let net: &mut [MaybeUninit<u32>; NET] = net.try_into().expect("a net");
                    let Some(cycle) = cycle(chunk * CHUNK + i) else {
                        out.fill(MaybeUninit::new(0));
                        net.fill(MaybeUninit::new(0));
                        bits.write(0);
                        continue;
                    };
                    if !crate::step::wide::dual_net(corners, cycle, net) {
                        dual_net(corners, cycle, net);
                    }
                    for (slot, c) in out.iter_mut().zip(cycle) {
                        slot.write(c);
                    }
                    // Its own point: the kernel makes the children at its four corners.
                    bits.write(match cycle.iter().all(|&c| child(c)) {
                        true => FACE_BIT,
                        false => 0,
                    });
                }
            });
        // SAFETY: every vertex's corners, net and own point were written above, whole (a panic
        // would have unwound past here).
        unsafe {
            cycles.set_len(4 * nv);
            nets.set_len(NET * nv);
            owned.set_len(nv);
        }
        // The place of corner `c` (of the level) in the cycle of its vertex, if it has one.
        let place = |c: u32| {
            let v = corner_verts[c as usize] as usize;
            let cycle = cycles.get(4 * v..4 * v + 4)?;
            let k = cycle.iter().position(|&x| x == c)?;
            (cycle[0] != cycle[1]).then_some((v, k as u16))
        };
        let mut rest: Vec<u32> = Vec::new();
        let leave = |rest: &mut Vec<u32>, point: usize| {
            memory::grow(rest, 1)?;
            rest.push(point as u32);
            Ok::<_, Error>(())
        };
        for (v, &bits) in owned.iter().enumerate() {
            if bits == 0 {
                leave(&mut rest, v)?;
            }
        }
        // An edge's point: the four children around its midpoint, at its first corner and the
        // next in either face; owned by the vertex of its first corner (whose outgoing edge it
        // is: edge `k` of that vertex's dual face).
        for (e, &[c, _]) in edge_corners.iter().enumerate() {
            let twin = match c {
                c if c < dead => corners.twin(c),
                _ => dead,
            };
            // Checked to name the edge: each fine vertex gets one owner, whose writes are
            // unchecked and in parallel.
            let fused = twin < dead
                && corner_edges[c as usize] as usize == e
                && [c, after(c, 1), twin, after(twin, 1)]
                    .iter()
                    .all(|&c| child(c));
            match fused.then(|| place(c)).flatten() {
                Some((v, k)) => owned[v] |= EDGE_BIT << k,
                None => leave(&mut rest, nv + e)?,
            }
        }
        // A face's point: its four children; owned by the vertex of its corner 0.
        for (f, &mask) in masks.iter().enumerate() {
            match (mask == 0xf).then(|| place(4 * f as u32)).flatten() {
                Some((v, k)) => owned[v] |= 1 << k,
                None => leave(&mut rest, nv + ne + f)?,
            }
        }
        Ok(DualGrid {
            cycles,
            nets,
            owned,
            rest,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::super::tests::times_made;
    use super::*;
    use crate::refinement::Refinement;
    use crate::step::regular::tests::{cube_grid, open_grid};
    use crate::{Options, Rules};

    /// Calls `check(degree, i, step, fused)` for the drawn last step of degrees 2 and 4, three
    /// levels, on a cube of grids (`i` = 0) and an open grid with a crease (`i` = 1).
    fn each_drawn_step(mut check: impl FnMut(u32, usize, &crate::step::Step, &Fused)) {
        for degree in [2, 4] {
            let options = Options {
                degree,
                levels: 3,
                rules: Rules::Averaging,
                ..Options::default()
            };
            for (i, (cage, _)) in [cube_grid(3), open_grid(7, 6, 10.0)].iter().enumerate() {
                let refinement = Refinement::new(cage, &options).unwrap();
                let step = refinement.drawn_step().unwrap().expect("a drawn last step");
                let fused = step.windows.and_then(|w| w.fused()).unwrap();
                check(degree, i, &step, fused);
            }
        }
    }

    /// The dual nets of the vectors are the loop's, id for id, on the drawn steps of degrees 2
    /// and 4 of a cube of grids and an open grid with a crease (boundaries: twins at the dead
    /// face). Without AVX2 both are the loop's.
    #[test]
    fn dual_nets_in_vectors_are_the_loops() {
        let mut nets = 0;
        each_drawn_step(|degree, _, step, fused| {
            let flags = crate::step::regular::Flags::of(step.coarse, step.curves).unwrap();
            for cycle in fused.cycles.chunks_exact(4).filter(|c| c[0] != c[1]) {
                let cycle: [u32; 4] = cycle.try_into().unwrap();
                let mut wide = [MaybeUninit::new(u32::MAX); NET];
                let mut scalar = [MaybeUninit::new(u32::MAX); NET];
                if !crate::step::wide::dual_net(flags.tables(), cycle, &mut wide) {
                    dual_net(flags.tables(), cycle, &mut wide);
                }
                dual_net(flags.tables(), cycle, &mut scalar);
                // SAFETY: both were initialised above.
                let read = |n: [MaybeUninit<u32>; NET]| n.map(|x| unsafe { x.assume_init() });
                assert_eq!(read(wide), read(scalar), "degree {degree}, cycle {cycle:?}");
                nets += 1;
            }
        });
        assert!(nets > 1000, "{nets} dual nets");
    }

    /// Every fine vertex of the drawn last step of degrees 2 and 4 ([`Fused::drawing`]) is
    /// made once, by the coarse vertex that owns it or by the average; most of the cube's are
    /// fused, and none where the children around it are not the tensor product's: curve
    /// vertices (the open grid's boundary and crease) and old vertices of another valence.
    #[test]
    fn every_drawing_point_is_made_once() {
        each_drawn_step(|degree, i, step, fused| {
            assert!(fused.dual() && fused.degree() == degree + 1);
            let ids = ClosureIds::of(step.coarse)
                .unwrap()
                .with_cycles(&fused.cycles)
                .unwrap();
            let n = step.fine.num_vertices;
            let made = times_made(fused, ids, n);
            assert!(
                made.iter().all(|&m| m == 1),
                "degree {degree}, cage {i}: a vertex made twice or never"
            );
            if i == 0 {
                let rest = fused.rest.len();
                assert!(rest < n / 10, "degree {degree}: {rest} of {n} not fused");
            }
            let rest = |w: u32| fused.rest.binary_search(&w).is_ok();
            for cv in step.curves.vertices() {
                assert!(rest(cv.vertex), "degree {degree}: curve vertex fused");
            }
            for v in 0..step.coarse.num_vertices {
                if step.coarse.corners_of_vertex(v).len() != 4 {
                    assert!(rest(v as u32), "degree {degree}: vertex {v} fused");
                }
            }
        });
    }
}
