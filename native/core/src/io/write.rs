//! OBJ writing: [`write_obj`] formats a polygon mesh (with optional face-varying UVs and
//! normals) in parallel into large buffers and writes it atomically: into a temporary file in
//! the target's directory (unnamed where the file system allows, so that even a killed process
//! leaves nothing), synced and renamed over the target only when complete. On any error or
//! interruption the temporary file is removed and an existing target is untouched.

use std::io::Write;
use std::ops::Range;
use std::path::Path;

use atomic_write_file::AtomicWriteFile;
use rayon::prelude::*;

use super::Interrupt;
use crate::error::{Error, Result};
use crate::memory;

/// Floating-point types [`write_obj`] prints, in their shortest form that reads back to the same
/// value (`0.1f32` as `0.1`): `f32` and `f64`.
pub trait ObjFloat: Copy + Send + Sync + ryu::Float + private::Sealed {
    /// Whether the value is neither NaN nor infinite.
    fn finite(self) -> bool;
}

impl ObjFloat for f32 {
    fn finite(self) -> bool {
        self.is_finite()
    }
}

impl ObjFloat for f64 {
    fn finite(self) -> bool {
        self.is_finite()
    }
}

mod private {
    pub trait Sealed {}
    impl Sealed for f32 {}
    impl Sealed for f64 {}
}

/// Texture coordinates of an [`ObjOutput`], 2 values per UV.
#[derive(Debug, Clone, Copy)]
pub enum Uvs<'a, T> {
    /// One UV per face corner, in corner order (face-varying data as bidegree computes it).
    PerCorner(&'a [T]),
    /// Shared UVs and the index of each face corner's UV.
    Indexed {
        /// 2 values per UV.
        values: &'a [T],
        /// One per face corner.
        indices: &'a [u32],
    },
}

/// A polygon mesh to write: face `f` uses `face_vertices[face_offsets[f]..face_offsets[f + 1]]`.
#[derive(Debug, Clone, Copy)]
pub struct ObjOutput<'a, T> {
    /// 3 values per vertex.
    pub points: &'a [T],
    /// `faces + 1` offsets into `face_vertices`, starting at 0.
    pub face_offsets: &'a [u32],
    /// Vertex of each face corner.
    pub face_vertices: &'a [u32],
    /// Texture coordinates (`vt`).
    pub uvs: Option<Uvs<'a, T>>,
    /// 3 values per face corner, written as one `vn` per corner.
    pub normals: Option<&'a [T]>,
}

/// Writes `mesh` as OBJ at `path`, atomically (see the module documentation). The input is
/// checked first (consistent arrays, finite values), so a refused mesh writes nothing;
/// `interrupt` is asked after every chunk (about 1 MB) whether to stop (its error is returned, the target is
/// untouched).
pub fn write_obj<T: ObjFloat>(
    path: &Path,
    mesh: &ObjOutput<'_, T>,
    interrupt: Interrupt<'_>,
) -> Result<()> {
    check_write_input(mesh)?;
    let io_error = |e: std::io::Error| Error::Io(format!("{}: {e}", path.display()));
    if path.is_dir() {
        return Err(Error::Io(format!("{}: is a directory", path.display())));
    }
    let mut file = AtomicWriteFile::open(path).map_err(io_error)?;
    write_text(&mut file, mesh, interrupt).map_err(|e| match e {
        Written::Io(e) => io_error(e),
        Written::Stopped(e) => e,
    })?;
    // Dropping `file` on an error above removes the temporary file; commit syncs and renames.
    file.commit().map_err(io_error)
}

/// Why writing the text stopped.
enum Written {
    Io(std::io::Error),
    Stopped(Error),
}

impl From<std::io::Error> for Written {
    fn from(e: std::io::Error) -> Self {
        Written::Io(e)
    }
}

fn write_text<T: ObjFloat>(
    file: &mut impl Write,
    mesh: &ObjOutput<'_, T>,
    interrupt: Interrupt<'_>,
) -> std::result::Result<(), Written> {
    file.write_all(b"# written by bidegree\n")?;
    write_vectors(file, b"v ", mesh.points, interrupt)?;
    let uv_values = match mesh.uvs {
        Some(Uvs::PerCorner(values)) | Some(Uvs::Indexed { values, .. }) => Some(values),
        None => None,
    };
    if let Some(values) = uv_values {
        let bound = |range: Range<usize>| range.len() * UV_LINE_BYTES;
        write_parallel(file, values.len() / 2, interrupt, bound, |range, out| {
            let mut buffer = ryu::Buffer::new();
            for t in range {
                out.extend_from_slice(b"vt ");
                push_float(out, &mut buffer, values[2 * t]);
                out.push(b' ');
                push_float(out, &mut buffer, values[2 * t + 1]);
                out.push(b'\n');
            }
        })?;
    }
    if let Some(values) = mesh.normals {
        write_vectors(file, b"vn ", values, interrupt)?;
    }

    let (offsets, vertices) = (mesh.face_offsets, mesh.face_vertices);
    let num_faces = offsets.len().saturating_sub(1);
    let with_normals = mesh.normals.is_some();
    let bound = |faces: Range<usize>| {
        let corners = (offsets[faces.end] - offsets[faces.start]) as usize;
        2 * faces.len() + corners * CORNER_BYTES
    };
    write_parallel(file, num_faces, interrupt, bound, |range, out| {
        let mut buffer = itoa::Buffer::new();
        for f in range {
            out.push(b'f');
            for c in offsets[f] as usize..offsets[f + 1] as usize {
                out.push(b' ');
                out.extend_from_slice(buffer.format(vertices[c] as u64 + 1).as_bytes());
                let uv = match mesh.uvs {
                    Some(Uvs::PerCorner(_)) => Some(c as u64),
                    Some(Uvs::Indexed { indices, .. }) => Some(indices[c] as u64),
                    None => None,
                };
                if let Some(t) = uv {
                    out.push(b'/');
                    out.extend_from_slice(buffer.format(t + 1).as_bytes());
                }
                if with_normals {
                    out.extend_from_slice(if uv.is_some() { b"/" } else { b"//" });
                    out.extend_from_slice(buffer.format(c as u64 + 1).as_bytes());
                }
            }
            out.push(b'\n');
        }
    })?;
    file.flush()?;
    Ok(())
}

/// Items formatted per parallel task (small in tests, so that chunking is exercised).
pub(super) const CHUNK_ITEMS: usize = if cfg!(test) { 64 } else { 1 << 15 };
/// Tasks per batch: the formatted text of one batch is held in memory at once.
pub(super) const CHUNKS_PER_BATCH: usize = 16;

/// Bytes a float takes at most in its shortest form (`-1.2345678901234567e-308`).
const FLOAT_BYTES: usize = 24;
/// Bytes a line `<tag>x y z` takes at most (tags of up to 3 bytes).
const VECTOR_LINE_BYTES: usize = 3 + 3 * FLOAT_BYTES + 3;
/// Bytes a line `vt u v` takes at most.
const UV_LINE_BYTES: usize = 3 + 2 * FLOAT_BYTES + 2;
/// Bytes a face corner ` v/t/n` takes at most (three 64-bit indices).
const CORNER_BYTES: usize = 3 * 21;

/// Writes `values` as lines `<tag>x y z`, three values per line.
fn write_vectors<W: Write, T: ObjFloat>(
    out: &mut W,
    tag: &[u8],
    values: &[T],
    interrupt: Interrupt<'_>,
) -> std::result::Result<(), Written> {
    let bound = |range: Range<usize>| range.len() * VECTOR_LINE_BYTES;
    write_parallel(out, values.len() / 3, interrupt, bound, |range, out| {
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
/// writes them in order, asking `interrupt` after every chunk. `bound(items)` is the most bytes
/// those items' text can take: each chunk's buffer is allocated at that size, fallibly (a face
/// of a million corners is one long line), so formatting never grows it.
fn write_parallel<W: Write>(
    out: &mut W,
    count: usize,
    interrupt: Interrupt<'_>,
    bound: impl Fn(Range<usize>) -> usize + Sync,
    format: impl Fn(Range<usize>, &mut Vec<u8>) + Sync,
) -> std::result::Result<(), Written> {
    let batch = CHUNK_ITEMS * CHUNKS_PER_BATCH;
    let mut start = 0;
    while start < count {
        let end = (start + batch).min(count);
        let buffers: Vec<Vec<u8>> = (start..end)
            .step_by(CHUNK_ITEMS)
            .collect::<Vec<_>>()
            .into_par_iter()
            .map(|chunk_start| {
                let items = chunk_start..(chunk_start + CHUNK_ITEMS).min(end);
                let mut buffer = memory::with_capacity(bound(items.clone()))?;
                format(items, &mut buffer);
                Ok(buffer)
            })
            .collect::<Result<_>>()
            .map_err(Written::Stopped)?;
        for buffer in &buffers {
            out.write_all(buffer)?;
            interrupt().map_err(Written::Stopped)?;
        }
        start = end;
    }
    Ok(())
}

/// The first non-finite value of `values` (in parallel), as the index of its item of `width`
/// values.
fn first_non_finite<T: ObjFloat>(values: &[T], width: usize) -> Option<usize> {
    values
        .par_iter()
        .position_first(|x| !x.finite())
        .map(|i| i / width)
}

fn check_write_input<T: ObjFloat>(mesh: &ObjOutput<'_, T>) -> Result<()> {
    let ObjOutput {
        points,
        face_offsets,
        face_vertices,
        uvs,
        normals,
    } = *mesh;
    let invalid = |message: String| Err(Error::InvalidInput(message));
    if !points.len().is_multiple_of(3) {
        return invalid(format!(
            "write_obj: points has {} values, not a multiple of 3",
            points.len()
        ));
    }
    let num_vertices = points.len() / 3;
    match (face_offsets.first(), face_offsets.last()) {
        (Some(&first), Some(&end)) => {
            if first != 0 {
                return invalid("write_obj: face_offsets must start at 0".into());
            }
            if face_offsets.windows(2).any(|w| w[1] < w[0]) {
                return invalid("write_obj: face_offsets must not decrease".into());
            }
            if end as usize != face_vertices.len() {
                return invalid(format!(
                    "write_obj: face_offsets ends at {end} but there are {} face corners",
                    face_vertices.len()
                ));
            }
        }
        _ if !face_vertices.is_empty() => {
            return invalid("write_obj: face_offsets is empty but face_vertices is not".into());
        }
        _ => {}
    }
    if let Some(&bad) = face_vertices
        .par_iter()
        .find_any(|&&v| v as usize >= num_vertices)
    {
        return invalid(format!(
            "write_obj: face vertex {bad} is out of range ({num_vertices} vertices)"
        ));
    }
    if let Some(vertex) = first_non_finite(points, 3) {
        return Err(Error::NonFinite { vertex });
    }
    let corners = face_vertices.len();
    match uvs {
        Some(Uvs::PerCorner(values)) if values.len() != 2 * corners => {
            return invalid(format!(
                "write_obj: {} uv values for {corners} face corners (2 per corner)",
                values.len()
            ));
        }
        Some(Uvs::Indexed { values, indices }) => {
            if !values.len().is_multiple_of(2) {
                return invalid(format!(
                    "write_obj: uv values has {} entries, not a multiple of 2",
                    values.len()
                ));
            }
            if indices.len() != corners {
                return invalid(format!(
                    "write_obj: {} uv indices for {corners} face corners",
                    indices.len()
                ));
            }
            let num_uvs = values.len() / 2;
            if let Some(&bad) = indices.par_iter().find_any(|&&t| t as usize >= num_uvs) {
                return invalid(format!(
                    "write_obj: uv index {bad} is out of range ({num_uvs} uvs)"
                ));
            }
        }
        Some(Uvs::PerCorner(_)) | None => {}
    }
    if let Some(Uvs::PerCorner(values) | Uvs::Indexed { values, .. }) = uvs {
        if let Some(uv) = first_non_finite(values, 2) {
            return invalid(format!("write_obj: uv {uv} is not finite"));
        }
    }
    if let Some(n) = normals {
        if n.len() != 3 * corners {
            return invalid(format!(
                "write_obj: {} normal values for {corners} face corners (3 per corner)",
                n.len()
            ));
        }
        if let Some(corner) = first_non_finite(n, 3) {
            return invalid(format!(
                "write_obj: the normal of face corner {corner} is not finite"
            ));
        }
    }
    Ok(())
}
