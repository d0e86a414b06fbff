//! OBJ reading and writing.
//!
//! This module owns the Wavefront OBJ format and nothing else:
//! - [`read_obj`] / [`parse_obj`] turn OBJ text into an [`ObjMesh`]: positions (`v`), texture
//!   coordinates (`vt`, face-varying), polygons (`f` in the forms `v`, `v/vt`, `v//vn`, `v/vt/vn`,
//!   with 1-based or negative (relative) indices), and the tag lines of OpenSubdiv's test shapes
//!   (`t crease`, `t corner`, `t interpolateboundary`). Normals, groups, objects, smoothing groups,
//!   materials, comments and statements it does not know are skipped.
//! - [`write_obj`] / [`write_obj_f32`] write a polygon mesh (with optional face-varying UVs and normals),
//!   formatting in parallel into large buffers.
//!
//! Malformed input is refused with [`Error::Io`] carrying `"path:LINE: message"`. The parser
//! checks the file itself (syntax, indices that refer to nothing, tag argument counts); the
//! topology (repeated vertices, manifoldness, orientation, creases that are no edges) is checked
//! when a [`crate::mesh::Cage`] is built from the result.

use std::fs::File;
use std::io::Write;
use std::ops::Range;
use std::path::Path;

use rayon::prelude::*;

use crate::error::{Error, Result};
use crate::options::Boundary;

/// A polygon mesh as read from an OBJ file. Indices are 0-based.
#[derive(Debug, Clone, Default)]
pub struct ObjMesh {
    /// Positions, 3 per vertex, interleaved (`x0 y0 z0 x1 ...`).
    pub points: Vec<f64>,
    /// Number of corners of each face.
    pub face_sizes: Vec<i64>,
    /// Vertex index of each face corner, faces one after the other.
    pub face_vertices: Vec<i64>,
    /// Texture coordinates, 2 per `vt` line (`u0 v0 u1 ...`).
    pub uvs: Vec<f64>,
    /// Texture coordinate index of each face corner (parallel to `face_vertices`); `Some` only
    /// when every face corner of the file names one.
    pub face_uvs: Option<Vec<i64>>,
    /// Crease edges `(a, b, sharpness)` from `t crease` tags.
    pub creases: Vec<(i64, i64, f32)>,
    /// Corner vertices `(vertex, sharpness)` from `t corner` tags.
    pub corners: Vec<(i64, f32)>,
    /// Boundary rule from a `t interpolateboundary` tag, if the file has one.
    pub boundary: Option<Boundary>,
}

impl ObjMesh {
    /// Number of vertices (`v` lines).
    pub fn num_vertices(&self) -> usize {
        self.points.len() / 3
    }

    /// Number of faces (`f` lines).
    pub fn num_faces(&self) -> usize {
        self.face_sizes.len()
    }
}

/// Reads and parses the OBJ file at `path`. Bytes that are not UTF-8 (in comments or names)
/// are tolerated. Errors name the file and the line: `"path:LINE: message"`.
pub fn read_obj(path: &Path) -> Result<ObjMesh> {
    let bytes = std::fs::read(path).map_err(|e| Error::Io(format!("{}: {e}", path.display())))?;
    let text = String::from_utf8_lossy(&bytes);
    parse_obj_named(&text, &path.display().to_string())
}

/// Parses OBJ text (see [`read_obj`]); errors are reported as `"<obj>:LINE: message"`.
pub fn parse_obj(text: &str) -> Result<ObjMesh> {
    parse_obj_named(text, "<obj>")
}

/// An index that could only be checked once the whole file was read (OBJ allows, in principle,
/// references to elements defined further down).
struct Pending {
    line: usize,
    index: i64,
    kind: PendingKind,
}

#[derive(Clone, Copy)]
enum PendingKind {
    Vertex,
    Uv,
    TagVertex,
}

struct Parser<'a> {
    name: &'a str,
    mesh: ObjMesh,
    face_uvs: Vec<i64>,
    corners_with_uv: usize,
    pending: Vec<Pending>,
}

/// A syntax error message, before the file name and line are added.
type LineResult<T> = std::result::Result<T, String>;

fn parse_obj_named(text: &str, name: &str) -> Result<ObjMesh> {
    let mut parser = Parser {
        name,
        mesh: ObjMesh::default(),
        face_uvs: Vec::new(),
        corners_with_uv: 0,
        pending: Vec::new(),
    };
    // Lines ending in a backslash continue on the next line (OBJ spec).
    let mut joined = String::new();
    let mut joined_start = 0;
    for (i, raw) in text.split('\n').enumerate() {
        let line_no = i + 1;
        let raw = raw.strip_suffix('\r').unwrap_or(raw);
        let content = match raw.find('#') {
            Some(pos) => &raw[..pos],
            None => raw,
        };
        let trimmed = content.trim_end();
        if let Some(head) = trimmed.strip_suffix('\\') {
            if joined.is_empty() {
                joined_start = line_no;
            }
            joined.push_str(head);
            joined.push(' ');
            continue;
        }
        if joined.is_empty() {
            parser.statement(trimmed, line_no)?;
        } else {
            joined.push_str(trimmed);
            let statement = std::mem::take(&mut joined);
            parser.statement(&statement, joined_start)?;
        }
    }
    if !joined.is_empty() {
        let statement = std::mem::take(&mut joined);
        parser.statement(&statement, joined_start)?;
    }
    parser.finish()
}

impl Parser<'_> {
    fn error(&self, line: usize, message: impl std::fmt::Display) -> Error {
        Error::Io(format!("{}:{line}: {message}", self.name))
    }

    fn statement(&mut self, statement: &str, line: usize) -> Result<()> {
        let mut tokens = statement.split_ascii_whitespace();
        let Some(keyword) = tokens.next() else {
            return Ok(());
        };
        let outcome = match keyword {
            "v" => self.vertex(tokens),
            "vt" => self.texture(tokens),
            "f" | "fo" => self.face(tokens, line),
            "t" => self.tag(tokens, line),
            // Normals, free-form data, grouping, display and material statements carry nothing
            // a subdivision cage needs; unknown statements are skipped like every reader does.
            _ => Ok(()),
        };
        outcome.map_err(|message| self.error(line, message))
    }

    fn vertex<'t>(&mut self, mut tokens: impl Iterator<Item = &'t str>) -> LineResult<()> {
        for axis in ["x", "y", "z"] {
            let token = tokens
                .next()
                .ok_or_else(|| format!("'v' needs 3 coordinates, {axis} is missing"))?;
            self.mesh.points.push(parse_f64(token)?);
        }
        // A 4th value (w) or vertex colours may follow: not used.
        Ok(())
    }

    fn texture<'t>(&mut self, mut tokens: impl Iterator<Item = &'t str>) -> LineResult<()> {
        let u = tokens
            .next()
            .ok_or_else(|| "'vt' needs at least 1 coordinate".to_string())?;
        let u = parse_f64(u)?;
        let v = match tokens.next() {
            Some(token) => parse_f64(token)?,
            None => 0.0,
        };
        self.mesh.uvs.push(u);
        self.mesh.uvs.push(v);
        Ok(())
    }

    fn face<'t>(&mut self, tokens: impl Iterator<Item = &'t str>, line: usize) -> LineResult<()> {
        let num_vertices = self.mesh.points.len() / 3;
        let num_uvs = self.mesh.uvs.len() / 2;
        let mut size = 0i64;
        for token in tokens {
            let mut parts = token.split('/');
            let vertex = parts.next().unwrap_or("");
            let uv = parts.next();
            let normal = parts.next();
            if parts.next().is_some() {
                return Err(format!(
                    "bad face corner '{token}' (forms: v, v/vt, v//vn, v/vt/vn)"
                ));
            }
            if vertex.is_empty() {
                return Err(format!("bad face corner '{token}': no vertex index"));
            }
            let v = self.resolve(vertex, num_vertices, line, PendingKind::Vertex)?;
            self.mesh.face_vertices.push(v);
            match uv {
                Some(uv) if !uv.is_empty() => {
                    let t = self.resolve(uv, num_uvs, line, PendingKind::Uv)?;
                    self.face_uvs.push(t);
                    self.corners_with_uv += 1;
                }
                _ => self.face_uvs.push(-1),
            }
            if let Some(normal) = normal {
                if !normal.is_empty() {
                    parse_index(normal)?;
                }
            }
            size += 1;
        }
        if size < 3 {
            return Err(format!("face has {size} vertices; faces need at least 3"));
        }
        self.mesh.face_sizes.push(size);
        Ok(())
    }

    /// Turns a 1-based or negative (relative) OBJ index into a 0-based one.
    fn resolve(
        &mut self,
        token: &str,
        count: usize,
        line: usize,
        kind: PendingKind,
    ) -> LineResult<i64> {
        let index = parse_index(token)?;
        let what = match kind {
            PendingKind::Uv => "texture coordinate",
            _ => "vertex",
        };
        if index == 0 {
            return Err(format!(
                "{what} index 0 is invalid (OBJ indices start at 1)"
            ));
        }
        if index < 0 {
            let resolved = count as i64 + index;
            if resolved < 0 {
                return Err(format!(
                    "relative {what} index {index} reaches before the first {what} ({count} defined so far)"
                ));
            }
            return Ok(resolved);
        }
        let resolved = index - 1;
        if resolved >= count as i64 {
            self.pending.push(Pending {
                line,
                index: resolved,
                kind,
            });
        }
        Ok(resolved)
    }

    fn tag<'t>(
        &mut self,
        mut tokens: impl Iterator<Item = &'t str>,
        line: usize,
    ) -> LineResult<()> {
        let name = tokens
            .next()
            .ok_or_else(|| "'t' needs a tag name".to_string())?;
        let counts = tokens
            .next()
            .ok_or_else(|| format!("tag '{name}' needs argument counts (ints/floats/strings)"))?;
        let counts: Vec<&str> = counts.split('/').collect();
        let parse_count = |s: &str| {
            s.parse::<usize>()
                .map_err(|_| format!("tag '{name}': bad argument counts '{}'", counts.join("/")))
        };
        if counts.len() != 3 {
            return Err(format!(
                "tag '{name}': argument counts must look like ints/floats/strings, got '{}'",
                counts.join("/")
            ));
        }
        let (num_ints, num_floats, num_strings) = (
            parse_count(counts[0])?,
            parse_count(counts[1])?,
            parse_count(counts[2])?,
        );
        let args: Vec<&str> = tokens.collect();
        let announced = num_ints
            .checked_add(num_floats)
            .and_then(|n| n.checked_add(num_strings));
        if announced != Some(args.len()) {
            return Err(format!(
                "tag '{name}' announces {num_ints}/{num_floats}/{num_strings} arguments but has {}",
                args.len()
            ));
        }
        let ints = args[..num_ints]
            .iter()
            .map(|s| parse_index(s))
            .collect::<LineResult<Vec<i64>>>()?;
        let floats = args[num_ints..num_ints + num_floats]
            .iter()
            .map(|s| parse_sharpness(s))
            .collect::<LineResult<Vec<f32>>>()?;
        match name {
            "crease" => {
                if num_ints < 2 || !num_ints.is_multiple_of(2) {
                    return Err(format!(
                        "tag 'crease' needs vertex pairs (an even number of vertices, at least 2), got {num_ints}"
                    ));
                }
                let num_edges = num_ints / 2;
                if num_floats != 1 && num_floats != num_edges {
                    return Err(format!(
                        "tag 'crease' needs 1 sharpness or one per edge ({num_edges}), got {num_floats}"
                    ));
                }
                self.tag_vertices(&ints, line)?;
                for (e, pair) in ints.chunks_exact(2).enumerate() {
                    let sharpness = floats[if num_floats == 1 { 0 } else { e }];
                    self.mesh.creases.push((pair[0], pair[1], sharpness));
                }
            }
            "corner" => {
                if num_ints == 0 {
                    return Err("tag 'corner' needs at least one vertex".to_string());
                }
                if num_floats != 1 && num_floats != num_ints {
                    return Err(format!(
                        "tag 'corner' needs 1 sharpness or one per vertex ({num_ints}), got {num_floats}"
                    ));
                }
                self.tag_vertices(&ints, line)?;
                for (i, &vertex) in ints.iter().enumerate() {
                    let sharpness = floats[if num_floats == 1 { 0 } else { i }];
                    self.mesh.corners.push((vertex, sharpness));
                }
            }
            "interpolateboundary" => {
                if num_ints != 1 {
                    return Err(format!(
                        "tag 'interpolateboundary' needs exactly 1 integer, got {num_ints}"
                    ));
                }
                self.mesh.boundary = Some(match ints[0] {
                    1 => Boundary::EdgeAndCorner,
                    2 => Boundary::EdgeOnly,
                    0 => {
                        return Err("interpolateboundary 0 (boundary faces as holes) is not \
                                    supported; use 1 (edge-and-corner) or 2 (edge-only)"
                            .to_string())
                    }
                    m => {
                        return Err(format!(
                        "unknown interpolateboundary mode {m} (1 = edge-and-corner, 2 = edge-only)"
                    ))
                    }
                });
            }
            // Other OpenSubdiv tags (creasemethod, facevaryinginterpolateboundary, ...) have no
            // meaning for this scheme.
            _ => {}
        }
        Ok(())
    }

    /// Checks the 0-based vertex indices of a tag; those past the vertices read so far are
    /// checked at the end of the file.
    fn tag_vertices(&mut self, ints: &[i64], line: usize) -> LineResult<()> {
        let count = (self.mesh.points.len() / 3) as i64;
        for &v in ints {
            if v < 0 {
                return Err(format!(
                    "tag vertex index {v} is negative (tags use 0-based indices)"
                ));
            }
            if v >= count {
                self.pending.push(Pending {
                    line,
                    index: v,
                    kind: PendingKind::TagVertex,
                });
            }
        }
        Ok(())
    }

    fn finish(mut self) -> Result<ObjMesh> {
        let num_vertices = self.mesh.points.len() / 3;
        let num_uvs = self.mesh.uvs.len() / 2;
        for p in &self.pending {
            let (count, what) = match p.kind {
                PendingKind::Vertex => (num_vertices, "vertex index"),
                PendingKind::Uv => (num_uvs, "texture coordinate index"),
                PendingKind::TagVertex => (num_vertices, "tag vertex index"),
            };
            if p.index >= count as i64 {
                // Report the index the way the file wrote it.
                let written = match p.kind {
                    PendingKind::TagVertex => p.index,
                    _ => p.index + 1,
                };
                let plural = match p.kind {
                    PendingKind::Uv => "texture coordinates",
                    _ => "vertices",
                };
                return Err(self.error(
                    p.line,
                    format!("{what} {written} is out of range (the file has {count} {plural})"),
                ));
            }
        }
        if self.corners_with_uv > 0 && self.corners_with_uv == self.face_uvs.len() {
            self.mesh.face_uvs = Some(std::mem::take(&mut self.face_uvs));
        }
        Ok(self.mesh)
    }
}

fn parse_f64(token: &str) -> LineResult<f64> {
    token
        .parse::<f64>()
        .map_err(|_| format!("'{token}' is not a number"))
}

fn parse_index(token: &str) -> LineResult<i64> {
    token
        .parse::<i64>()
        .map_err(|_| format!("'{token}' is not an integer index"))
}

fn parse_sharpness(token: &str) -> LineResult<f32> {
    let s = token
        .parse::<f32>()
        .map_err(|_| format!("'{token}' is not a sharpness value"))?;
    if s.is_nan() || s < 0.0 {
        return Err(format!("sharpness {token} must be a number >= 0"));
    }
    Ok(s)
}

/// Floating-point types [`write_obj`] can print: shortest representation that reads back to
/// the same value.
trait ObjFloat: Copy + Send + Sync + ryu::Float {}
impl ObjFloat for f32 {}
impl ObjFloat for f64 {}

/// Writes a polygon mesh as OBJ: `points` has 3 values per vertex, face `f` uses
/// `face_vertices[face_offsets[f]..face_offsets[f + 1]]`, `uvs`, if given, is
/// `(values, indices)` with 2 values per UV and one index per face corner (face-varying), and
/// `normals`, if given, has 3 values per face corner (written as one `vn` per corner).
/// Numbers are written in their shortest exact form; the text is formatted in parallel.
pub fn write_obj(
    path: &Path,
    points: &[f64],
    face_offsets: &[u32],
    face_vertices: &[u32],
    uvs: Option<(&[f64], &[u32])>,
    normals: Option<&[f64]>,
) -> Result<()> {
    write_obj_generic(path, points, face_offsets, face_vertices, uvs, normals)
}

/// [`write_obj`] for single-precision data (numbers are printed in their shortest `f32` form,
/// so `0.1f32` is written as `0.1`).
pub fn write_obj_f32(
    path: &Path,
    points: &[f32],
    face_offsets: &[u32],
    face_vertices: &[u32],
    uvs: Option<(&[f32], &[u32])>,
    normals: Option<&[f32]>,
) -> Result<()> {
    write_obj_generic(path, points, face_offsets, face_vertices, uvs, normals)
}

/// Items formatted per parallel task (small in tests, so that chunking is exercised).
const CHUNK_ITEMS: usize = if cfg!(test) { 64 } else { 1 << 15 };
/// Tasks per batch: the formatted text of one batch is held in memory at once.
const CHUNKS_PER_BATCH: usize = 16;

fn write_obj_generic<T: ObjFloat>(
    path: &Path,
    points: &[T],
    face_offsets: &[u32],
    face_vertices: &[u32],
    uvs: Option<(&[T], &[u32])>,
    normals: Option<&[T]>,
) -> Result<()> {
    check_write_input(points, face_offsets, face_vertices, uvs)?;
    if let Some(n) = normals {
        if n.len() != 3 * face_vertices.len() {
            return Err(Error::InvalidInput(format!(
                "write_obj: {} normal values for {} face corners (3 per corner)",
                n.len(),
                face_vertices.len()
            )));
        }
    }
    let io_error = |e: std::io::Error| Error::Io(format!("{}: {e}", path.display()));
    let mut file = File::create(path).map_err(io_error)?;
    file.write_all(b"# written by bidegree\n")
        .map_err(io_error)?;

    write_vectors(&mut file, b"v ", points).map_err(io_error)?;

    if let Some((values, _)) = uvs {
        write_parallel(&mut file, values.len() / 2, |range, out| {
            let mut buffer = ryu::Buffer::new();
            for t in range {
                out.extend_from_slice(b"vt ");
                push_float(out, &mut buffer, values[2 * t]);
                out.push(b' ');
                push_float(out, &mut buffer, values[2 * t + 1]);
                out.push(b'\n');
            }
        })
        .map_err(io_error)?;
    }

    if let Some(values) = normals {
        write_vectors(&mut file, b"vn ", values).map_err(io_error)?;
    }

    let num_faces = face_offsets.len().saturating_sub(1);
    let uv_indices = uvs.map(|(_, indices)| indices);
    let with_normals = normals.is_some();
    write_parallel(&mut file, num_faces, |range, out| {
        let mut buffer = itoa::Buffer::new();
        for f in range {
            out.push(b'f');
            for c in face_offsets[f] as usize..face_offsets[f + 1] as usize {
                out.push(b' ');
                out.extend_from_slice(buffer.format(face_vertices[c] as u64 + 1).as_bytes());
                if let Some(indices) = uv_indices {
                    out.push(b'/');
                    out.extend_from_slice(buffer.format(indices[c] as u64 + 1).as_bytes());
                }
                if with_normals {
                    out.extend_from_slice(if uv_indices.is_some() { b"/" } else { b"//" });
                    out.extend_from_slice(buffer.format(c as u64 + 1).as_bytes());
                }
            }
            out.push(b'\n');
        }
    })
    .map_err(io_error)?;
    file.flush().map_err(io_error)
}

/// Writes `values` as lines `<tag>x y z`, three values per line.
fn write_vectors<W: Write, T: ObjFloat>(
    out: &mut W,
    tag: &[u8],
    values: &[T],
) -> std::io::Result<()> {
    write_parallel(out, values.len() / 3, |range, out| {
        let mut buffer = ryu::Buffer::new();
        for v in range {
            out.extend_from_slice(tag);
            push_float(out, &mut buffer, values[3 * v]);
            out.push(b' ');
            push_float(out, &mut buffer, values[3 * v + 1]);
            out.push(b' ');
            push_float(out, &mut buffer, values[3 * v + 2]);
            out.push(b'\n');
        }
    })
}

/// Appends the shortest round-trip form of `x`, without a trailing `.0`.
#[inline]
fn push_float<T: ObjFloat>(out: &mut Vec<u8>, buffer: &mut ryu::Buffer, x: T) {
    let text = buffer.format(x).as_bytes();
    out.extend_from_slice(text.strip_suffix(b".0").unwrap_or(text));
}

/// Formats `count` items in parallel chunks (in a bounded number of buffers at a time) and
/// writes them in order.
fn write_parallel<W: Write>(
    out: &mut W,
    count: usize,
    format: impl Fn(Range<usize>, &mut Vec<u8>) + Sync,
) -> std::io::Result<()> {
    let batch = CHUNK_ITEMS * CHUNKS_PER_BATCH;
    let mut start = 0;
    while start < count {
        let end = (start + batch).min(count);
        let buffers: Vec<Vec<u8>> = (start..end)
            .step_by(CHUNK_ITEMS)
            .collect::<Vec<_>>()
            .into_par_iter()
            .map(|chunk_start| {
                let mut buffer = Vec::with_capacity(CHUNK_ITEMS * 48);
                format(
                    chunk_start..(chunk_start + CHUNK_ITEMS).min(end),
                    &mut buffer,
                );
                buffer
            })
            .collect();
        for buffer in &buffers {
            out.write_all(buffer)?;
        }
        start = end;
    }
    Ok(())
}

fn check_write_input<T>(
    points: &[T],
    face_offsets: &[u32],
    face_vertices: &[u32],
    uvs: Option<(&[T], &[u32])>,
) -> Result<()> {
    let invalid = |message: String| Err(Error::InvalidInput(message));
    if !points.len().is_multiple_of(3) {
        return invalid(format!(
            "write_obj: points has {} values, not a multiple of 3",
            points.len()
        ));
    }
    let num_vertices = points.len() / 3;
    if face_offsets.is_empty() {
        if !face_vertices.is_empty() {
            return invalid("write_obj: face_offsets is empty but face_vertices is not".into());
        }
    } else {
        if face_offsets[0] != 0 {
            return invalid("write_obj: face_offsets must start at 0".into());
        }
        if face_offsets.windows(2).any(|w| w[1] < w[0]) {
            return invalid("write_obj: face_offsets must not decrease".into());
        }
        if *face_offsets.last().unwrap() as usize != face_vertices.len() {
            return invalid(format!(
                "write_obj: face_offsets ends at {} but there are {} face corners",
                face_offsets.last().unwrap(),
                face_vertices.len()
            ));
        }
    }
    if let Some(&bad) = face_vertices
        .par_iter()
        .find_any(|&&v| v as usize >= num_vertices)
    {
        return invalid(format!(
            "write_obj: face vertex {bad} is out of range ({num_vertices} vertices)"
        ));
    }
    if let Some((values, indices)) = uvs {
        if !values.len().is_multiple_of(2) {
            return invalid(format!(
                "write_obj: uv values has {} entries, not a multiple of 2",
                values.len()
            ));
        }
        if indices.len() != face_vertices.len() {
            return invalid(format!(
                "write_obj: {} uv indices for {} face corners",
                indices.len(),
                face_vertices.len()
            ));
        }
        let num_uvs = values.len() / 2;
        if let Some(&bad) = indices.par_iter().find_any(|&&t| t as usize >= num_uvs) {
            return invalid(format!(
                "write_obj: uv index {bad} is out of range ({num_uvs} uvs)"
            ));
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn io_message(text: &str) -> String {
        match parse_obj(text) {
            Err(Error::Io(message)) => message,
            other => panic!("expected an Io error, got {other:?}"),
        }
    }

    fn temp_path(name: &str) -> std::path::PathBuf {
        let dir = std::env::temp_dir().join(format!("bidegree-io-test-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        dir.join(name)
    }

    #[test]
    fn reads_vertices_faces_and_all_corner_forms() {
        let mesh = parse_obj(
            "# a comment\n\
             mtllib x.mtl\n\
             o thing\n\
             v 0 0 0\n\
             v 1 0 0 1.0\n\
             v 1 1 0 0.5 0.5 0.5\n\
             v 0 1 0\n\
             vn 0 0 1\n\
             \n\
             g group\n\
             s off\n\
             usemtl m\n\
             f 1 2 3\n\
             f 1//1 3//1 4//1   # trailing comment\n\
             l 1 2\n",
        )
        .unwrap();
        assert_eq!(mesh.num_vertices(), 4);
        assert_eq!(mesh.points[3..6], [1.0, 0.0, 0.0]);
        assert_eq!(mesh.face_sizes, vec![3, 3]);
        assert_eq!(mesh.face_vertices, vec![0, 1, 2, 0, 2, 3]);
        assert_eq!(mesh.face_uvs, None);
        assert!(mesh.creases.is_empty() && mesh.corners.is_empty());
        assert_eq!(mesh.boundary, None);
    }

    #[test]
    fn reads_uvs_and_negative_indices() {
        let mesh = parse_obj(
            "v 0 0 0\r\nv 1 0 0\r\nv 1 1 0\r\nv 0 1 0\r\n\
             vt 0 0\r\nvt 1 0\r\nvt 1 1 0\r\nvt 0.5\r\n\
             f -4/-4 -3/-3/1 -2/-2 -1/-1\r\n",
        )
        .unwrap();
        assert_eq!(mesh.face_vertices, vec![0, 1, 2, 3]);
        assert_eq!(mesh.uvs, vec![0.0, 0.0, 1.0, 0.0, 1.0, 1.0, 0.5, 0.0]);
        assert_eq!(mesh.face_uvs, Some(vec![0, 1, 2, 3]));
    }

    #[test]
    fn uvs_only_when_every_corner_has_one() {
        let mesh =
            parse_obj("v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nvt 0 0\nf 1/1 2/1 3/1\nf 1 3 4\n")
                .unwrap();
        assert_eq!(mesh.face_uvs, None);
        assert_eq!(mesh.uvs.len(), 2);
    }

    #[test]
    fn reads_tags() {
        let mesh = parse_obj(
            "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nf 1 2 3 4\n\
             t crease 2/1/0 0 1 2.5\n\
             t crease 4/1/0 1 2 2 3 inf\n\
             t crease 4/2/0 3 0 0 1 1 10\n\
             t corner 1/1/0 2 10\n\
             t corner 2/2/0 0 1 0.5 1.5\n\
             t interpolateboundary 1/0/0 1\n\
             t creasemethod 0/0/1 chaikin\n",
        )
        .unwrap();
        assert_eq!(
            mesh.creases,
            vec![
                (0, 1, 2.5),
                (1, 2, f32::INFINITY),
                (2, 3, f32::INFINITY),
                (3, 0, 1.0),
                (0, 1, 10.0)
            ]
        );
        assert_eq!(mesh.corners, vec![(2, 10.0), (0, 0.5), (1, 1.5)]);
        assert_eq!(mesh.boundary, Some(Boundary::EdgeAndCorner));
        let mesh = parse_obj("v 0 0 0\nt interpolateboundary 1/0/0 2\n").unwrap();
        assert_eq!(mesh.boundary, Some(Boundary::EdgeOnly));
    }

    #[test]
    fn tags_may_precede_vertices() {
        let mesh = parse_obj("t corner 1/1/0 2 3\nv 0 0 0\nv 1 0 0\nv 1 1 0\nf 1 2 3\n").unwrap();
        assert_eq!(mesh.corners, vec![(2, 3.0)]);
    }

    #[test]
    fn line_continuation() {
        let mesh = parse_obj("v 0 0 0\nv 1 0 0\nv 1 1 0\nf 1 \\\n 2 3\nv 0 1 0\n").unwrap();
        assert_eq!(mesh.face_vertices, vec![0, 1, 2]);
        assert_eq!(mesh.num_vertices(), 4);
    }

    #[test]
    fn forward_references_are_checked_at_the_end() {
        let mesh = parse_obj("f 1 2 3\nv 0 0 0\nv 1 0 0\nv 1 1 0\n").unwrap();
        assert_eq!(mesh.face_vertices, vec![0, 1, 2]);
        let message = io_message("v 0 0 0\nv 1 0 0\nf 1 2 3\nv 1 1 0\nf 1 2 5\n");
        assert_eq!(
            message,
            "<obj>:5: vertex index 5 is out of range (the file has 3 vertices)"
        );
    }

    #[test]
    fn errors_name_the_line() {
        let cases: &[(&str, &str)] = &[
            ("v 0 0\n", "<obj>:1: 'v' needs 3 coordinates, z is missing"),
            ("v 0 0 0\nv 0 x 0\n", "<obj>:2: 'x' is not a number"),
            ("v 0 0 0\nv 1 0 0\nf 1 2\n", "<obj>:3: face has 2 vertices"),
            (
                "v 0 0 0\nv 1 0 0\nv 1 1 0\n\nf 1 0 2\n",
                "<obj>:5: vertex index 0 is invalid",
            ),
            (
                "v 0 0 0\nv 1 0 0\nf -1 -2 -3\n",
                "<obj>:3: relative vertex index -3 reaches",
            ),
            (
                "v 0 0 0\nv 1 0 0\nv 1 1 0\nf 1/1 2/1 3/1\n",
                "<obj>:4: texture coordinate index 1 is out of range",
            ),
            (
                "v 0 0 0\nv 1 0 0\nv 1 1 0\nf 1 2 3/1/1/1\n",
                "<obj>:4: bad face corner",
            ),
            (
                "v 0 0 0\nv 1 0 0\nv 1 1 0\nf 1 2 a\n",
                "<obj>:4: 'a' is not an integer index",
            ),
            (
                "v 0 0 0\nv 1 0 0\nv 1 1 0\nf 1 2 /1\n",
                "<obj>:4: bad face corner '/1'",
            ),
            ("vt\n", "<obj>:1: 'vt' needs at least 1 coordinate"),
            (
                "v 0 0 0\nt crease 2/1/0 0 1\n",
                "<obj>:2: tag 'crease' announces 2/1/0 arguments but has 2",
            ),
            (
                "v 0 0 0\nt crease 3/1/0 0 1 2 1\n",
                "<obj>:2: tag 'crease' needs vertex pairs",
            ),
            (
                "v 0 0 0\nt crease 2/1/0 0 1 -1\n",
                "<obj>:2: sharpness -1 must be a number >= 0",
            ),
            (
                "v 0 0 0\nt crease 2/1/0 0 -1 1\n",
                "<obj>:2: tag vertex index -1 is negative",
            ),
            (
                "v 0 0 0\nt crease 2/1/0 0 1 1\n",
                "<obj>:2: tag vertex index 1 is out of range (the file has 1 vertices)",
            ),
            (
                "v 0 0 0\nt crease 2/1/0 0 1 nan\n",
                "<obj>:2: sharpness nan",
            ),
            (
                "v 0 0 0\nt crease 4/3/0 0 1 1 2 1 1 1\n",
                "<obj>:2: tag 'crease' needs 1 sharpness or one per edge (2), got 3",
            ),
            (
                "v 0 0 0\nt corner 0/1/0 1\n",
                "<obj>:2: tag 'corner' needs at least one vertex",
            ),
            (
                "v 0 0 0\nt corner 1/0/0 0\n",
                "<obj>:2: tag 'corner' needs 1 sharpness",
            ),
            (
                "t interpolateboundary 1/0/0 0\n",
                "<obj>:1: interpolateboundary 0",
            ),
            (
                "t interpolateboundary 1/0/0 7\n",
                "<obj>:1: unknown interpolateboundary mode 7",
            ),
            (
                "t interpolateboundary 0/0/0\n",
                "<obj>:1: tag 'interpolateboundary' needs exactly 1",
            ),
            (
                "t interpolateboundary 1/0 1\n",
                "<obj>:1: tag 'interpolateboundary': argument counts",
            ),
            ("t crease\n", "<obj>:1: tag 'crease' needs argument counts"),
            (
                "t crease x/1/0 0 1 1\n",
                "<obj>:1: tag 'crease': bad argument counts 'x/1/0'",
            ),
            (
                "t crease 18446744073709551615/1/0 0 1 1\n",
                "<obj>:1: tag 'crease' announces 18446744073709551615/1/0 arguments but has 3",
            ),
        ];
        for (text, expected) in cases {
            let message = io_message(text);
            assert!(
                message.starts_with(expected),
                "{text:?}: got {message:?}, expected {expected:?}"
            );
            assert!(!message.contains('\n'), "multi-line message {message:?}");
        }
    }

    #[test]
    fn read_obj_names_the_file() {
        let path = temp_path("bad.obj");
        std::fs::write(&path, "v 0 0 0\nv 1 0 0\nv 1 1 0\nf 1 2 9\n").unwrap();
        match read_obj(&path) {
            Err(Error::Io(message)) => {
                assert_eq!(
                    message,
                    format!(
                        "{}:4: vertex index 9 is out of range (the file has 3 vertices)",
                        path.display()
                    )
                )
            }
            other => panic!("{other:?}"),
        }
        let missing = temp_path("missing.obj");
        match read_obj(&missing) {
            Err(Error::Io(message)) => {
                assert!(message.starts_with(&format!("{}: ", missing.display())))
            }
            other => panic!("{other:?}"),
        }
        // Latin-1 bytes in a comment do not stop the reader.
        std::fs::write(&path, b"# caf\xe9\nv 0 0 0\nv 1 0 0\nv 1 1 0\nf 1 2 3\n").unwrap();
        assert_eq!(read_obj(&path).unwrap().num_faces(), 1);
    }

    #[test]
    fn write_then_read_round_trip() {
        let points = [
            0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 1.0, 1.0, 0.1, 0.0, 1.0, -2.5e-7, 0.5, 0.5, 1e20,
        ];
        let offsets = [0u32, 4, 7, 10, 13, 16];
        let vertices = [0u32, 1, 2, 3, 0, 1, 4, 1, 2, 4, 2, 3, 4, 3, 0, 4];
        let uv_values = [
            0.0,
            0.0,
            1.0,
            0.0,
            1.0,
            1.0,
            0.0,
            1.0,
            0.3333333333333333,
            0.5,
        ];
        let uv_indices = [0u32, 1, 2, 3, 0, 1, 4, 1, 2, 4, 2, 3, 4, 3, 0, 4];
        let path = temp_path("round.obj");
        write_obj(
            &path,
            &points,
            &offsets,
            &vertices,
            Some((&uv_values, &uv_indices)),
            None,
        )
        .unwrap();
        let mesh = read_obj(&path).unwrap();
        assert_eq!(mesh.points, points);
        assert_eq!(mesh.face_sizes, vec![4, 3, 3, 3, 3]);
        assert_eq!(
            mesh.face_vertices,
            vertices.iter().map(|&v| v as i64).collect::<Vec<_>>()
        );
        assert_eq!(mesh.uvs, uv_values);
        assert_eq!(
            mesh.face_uvs,
            Some(uv_indices.iter().map(|&v| v as i64).collect::<Vec<_>>())
        );
        let text = std::fs::read_to_string(&path).unwrap();
        assert!(text.contains("\nv 1 1 0.1\n"), "{text}");
        assert!(text.contains("\nf 1/1 2/2 3/3 4/4\n"), "{text}");

        write_obj(&path, &points, &offsets, &vertices, None, None).unwrap();
        let mesh = read_obj(&path).unwrap();
        assert_eq!(mesh.face_uvs, None);
        assert!(mesh.uvs.is_empty());
    }

    #[test]
    fn normals_are_written_per_corner() {
        let path = temp_path("normals.obj");
        let points = [0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0];
        let normals = [0.0, 0.0, 1.0, 0.0, 0.6, 0.8, 0.0, 0.0, 1.0];
        write_obj(&path, &points, &[0, 3], &[0, 1, 2], None, Some(&normals)).unwrap();
        let text = std::fs::read_to_string(&path).unwrap();
        assert!(text.contains("\nvn 0 0.6 0.8\n"), "{text}");
        assert!(text.contains("\nf 1//1 2//2 3//3\n"), "{text}");
        let uv = [0.0, 0.0, 1.0, 0.0, 0.0, 1.0];
        let uvs = Some((&uv[..], &[0u32, 1, 2][..]));
        write_obj(&path, &points, &[0, 3], &[0, 1, 2], uvs, Some(&normals)).unwrap();
        let text = std::fs::read_to_string(&path).unwrap();
        assert!(text.contains("\nf 1/1/1 2/2/2 3/3/3\n"), "{text}");
        assert_eq!(read_obj(&path).unwrap().points, points);
        assert!(matches!(
            write_obj(
                &path,
                &points,
                &[0, 3],
                &[0, 1, 2],
                None,
                Some(&normals[..6])
            ),
            Err(Error::InvalidInput(_))
        ));
    }

    #[test]
    fn write_f32_uses_short_numbers() {
        let path = temp_path("f32.obj");
        write_obj_f32(
            &path,
            &[0.1f32, 0.2, 0.3, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0],
            &[0, 3],
            &[0, 1, 2],
            None,
            None,
        )
        .unwrap();
        let text = std::fs::read_to_string(&path).unwrap();
        assert!(text.contains("\nv 0.1 0.2 0.3\nv 1 0 0\n"), "{text}");
        let mesh = read_obj(&path).unwrap();
        assert_eq!(mesh.points[0] as f32, 0.1f32);
    }

    #[test]
    fn write_many_chunks_in_order() {
        // More vertices and faces than one batch, so chunks and batches are both exercised.
        let n = CHUNK_ITEMS * CHUNKS_PER_BATCH + CHUNK_ITEMS * 3 + 17;
        let points: Vec<f64> = (0..3 * n).map(|i| i as f64).collect();
        let offsets: Vec<u32> = (0..=n as u32).map(|f| 3 * f).collect();
        let vertices: Vec<u32> = (0..3 * n as u32)
            .map(|c| (c / 3 + c % 3) % n as u32)
            .collect();
        let path = temp_path("large.obj");
        write_obj(&path, &points, &offsets, &vertices, None, None).unwrap();
        let mesh = read_obj(&path).unwrap();
        assert_eq!(mesh.points, points);
        assert_eq!(
            mesh.face_vertices,
            vertices.iter().map(|&v| v as i64).collect::<Vec<_>>()
        );
    }

    #[test]
    fn write_refuses_inconsistent_input() {
        let path = temp_path("never.obj");
        let points = [0.0; 9];
        let bad: &[(&[f64], &[u32], &[u32])] = &[
            (&points[..8], &[0, 3], &[0, 1, 2]),
            (&points, &[1, 3], &[0, 1, 2]),
            (&points, &[0, 2], &[0, 1, 2]),
            (&points, &[0, 3], &[0, 1, 3]),
            (&points, &[], &[0, 1, 2]),
            (&points, &[0, 3, 2], &[0, 1, 2]),
        ];
        for (p, o, v) in bad {
            assert!(
                matches!(
                    write_obj(&path, p, o, v, None, None),
                    Err(Error::InvalidInput(_))
                ),
                "{o:?} {v:?}"
            );
        }
        let uv = [0.0; 4];
        assert!(matches!(
            write_obj(
                &path,
                &points,
                &[0, 3],
                &[0, 1, 2],
                Some((&uv, &[0, 1])),
                None
            ),
            Err(Error::InvalidInput(_))
        ));
        assert!(matches!(
            write_obj(
                &path,
                &points,
                &[0, 3],
                &[0, 1, 2],
                Some((&uv, &[0, 1, 2])),
                None
            ),
            Err(Error::InvalidInput(_))
        ));
        assert!(!path.exists());
        let unwritable = temp_path("no-such-dir").join("x.obj");
        assert!(matches!(
            write_obj(&unwritable, &points, &[0, 3], &[0, 1, 2], None, None),
            Err(Error::Io(_))
        ));
    }

    #[test]
    fn empty_input_gives_an_empty_mesh() {
        let mesh = parse_obj("").unwrap();
        assert_eq!(mesh.num_vertices(), 0);
        assert_eq!(mesh.num_faces(), 0);
        let path = temp_path("empty.obj");
        write_obj(&path, &[], &[], &[], None, None).unwrap();
        assert_eq!(read_obj(&path).unwrap().num_faces(), 0);
    }
}
