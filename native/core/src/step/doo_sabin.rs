//! The classic Doo-Sabin step, in one pass over the faces of the fine level: face `c` of `fine`
//! (corner `c` of `coarse`, at vertex `v`) takes the original Doo-Sabin combination of the
//! points of the polygon it belongs to (the corners of `c`'s face when the data is primal, the
//! faces around `v` when dual) unless `v` is on the step's curve network; there it takes the
//! averaging step of degree 2 (replication, one dual -> primal average with the 1-D values, one
//! primal -> dual average), in closed form from the input, so that boundaries and creases are
//! those of the averaging scheme. The input is read, never copied.

use std::borrow::Cow;

use super::{blend, curve_to_dual, first_point, CurveData, LevelData, Step, Tables};
use crate::parallel::gather_into;
use crate::scalar::{add, mad, scale, zero, Scalar, Value};
use crate::scheme::doo_sabin_weight;

/// Faces of up to this many corners take their weights from a table.
const TABLE: usize = 16;

impl<T: Scalar, const N: usize> LevelData<'_, T, N> {
    /// The Doo-Sabin step (see the module documentation).
    pub(super) fn doo_sabin(&mut self, step: &Step) {
        let (coarse, curves) = (step.coarse, step.curves);
        let (nv, ne) = (coarse.num_vertices, coarse.num_edges());
        self.replicate_curves(curves);
        let primal = self.primal;
        let mut out = if primal {
            self.take_faces()
        } else {
            self.fresh()
        };
        let before: &[Value<T, N>] = if primal { &self.vertices } else { &self.faces };
        // Fine vertex `w` after replication and the first (dual -> primal) average.
        let t = Tables::of(coarse);
        let point = |w: usize| first_point(&t, before, primal, w);
        let curve = self.curve_to_primal(curves, point);
        let blended = |w: usize| -> Value<T, N> {
            let mut p = point(w);
            if let Some(i) = curves.vertex_index(w as u32) {
                blend(&mut p, curve[i as usize], &curves.vertices()[i as usize]);
            }
            p
        };
        let table: Vec<Vec<T>> = (0..=TABLE)
            .map(|k| {
                (0..k)
                    .map(|i| T::from_f64(doo_sabin_weight(i, k)))
                    .collect()
            })
            .collect();
        let weight = |i: usize, k: usize| {
            if k <= TABLE {
                table[k][i]
            } else {
                T::from_f64(doo_sabin_weight(i, k))
            }
        };
        let quarter = T::from_f64(0.25);
        gather_into(&mut out, coarse.num_corners(), |c| {
            let v = coarse.corner_verts[c];
            if curves.vertex_index(v).is_some() {
                // The fine face of corner c: v, edge(c), face(c), edge(prev c).
                let q = [
                    v as usize,
                    nv + coarse.corner_edges()[c] as usize,
                    nv + ne + coarse.face_of(c),
                    nv + coarse.corner_edges()[coarse.prev(c)] as usize,
                ];
                let s = add(
                    add(blended(q[0]), blended(q[1])),
                    add(blended(q[2]), blended(q[3])),
                );
                return scale(s, quarter);
            }
            let mut out = zero();
            if primal {
                let k = coarse.face_corners(coarse.face_of(c)).len();
                let mut at = c;
                for i in 0..k {
                    out = mad(out, weight(i, k), before[coarse.corner_verts[at] as usize]);
                    at = coarse.next(at);
                }
            } else {
                let k = coarse.corners_of_vertex(v as usize).len();
                let mut at = c;
                for i in 0..k {
                    out = mad(out, weight(i, k), before[coarse.face_of(at)]);
                    // Rotate around v (an interior vertex: it is not on the curve network).
                    at = coarse.next_around_vertex(at).unwrap_or(at);
                }
            }
            out
        });
        let dual = curve_to_dual(curves, &curve);
        // The input is free now.
        if primal {
            if let Cow::Owned(old) = std::mem::replace(&mut self.vertices, Cow::Borrowed(&[])) {
                self.spare = old;
            }
        } else if let Cow::Owned(old) = std::mem::replace(&mut self.faces, Cow::Borrowed(&[])) {
            self.spare = old;
        }
        self.faces = Cow::Owned(out);
        self.curve = CurveData::Dual(dual);
        self.primal = false;
    }
}
