//! OBJ reading: [`read_obj`] streams a file in chunks (never holding the whole text), under a
//! byte limit and a memory budget for what it builds; [`parse_obj`] parses text. Both give an
//! [`ObjMesh`] that remembers the line of each face, crease and corner, so that an error found
//! later in the mesh can be told in the file's terms ([`ObjSource::restate`]).
//!
//! Lines end with LF, CRLF or CR; a UTF-8 byte order mark is skipped; a NUL byte means the file
//! is not OBJ text (so `/dev/zero` is refused at its first byte). Bytes that are not UTF-8 (in
//! comments or names) are tolerated.

use std::collections::HashMap;
use std::fs::File;
use std::io::Read;
use std::path::Path;

use super::{Interrupt, ObjMesh};
use crate::error::{Error, Result};
use crate::memory::{self, default_memory_budget};
use crate::{Boundary, Cage, Creasing};

/// Largest input [`ReadOptions`] accepts by default: 2 GiB.
pub const DEFAULT_MAX_INPUT_BYTES: u64 = 2 << 30;

/// Limits of a read.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ReadOptions {
    /// Bytes of input accepted; a larger file is refused (a regular file before it is read).
    pub max_bytes: u64,
    /// Bytes the mesh being built may take; past that the read stops with
    /// [`Error::MemoryBudget`] (an adversarial file of short lines, `f 1 2 3`, builds several
    /// times its size).
    pub memory_budget: u64,
}

impl Default for ReadOptions {
    fn default() -> Self {
        ReadOptions {
            max_bytes: DEFAULT_MAX_INPUT_BYTES,
            memory_budget: default_memory_budget(),
        }
    }
}

/// Bytes read from the file at a time (also how often `interrupt` and the memory are checked;
/// tiny in tests, so that lines and line ends split across reads are exercised).
const CHUNK_BYTES: usize = if cfg!(test) { 7 } else { 1 << 20 };

/// Reads and parses the OBJ file at `path`, streaming it. Errors name the file and the line:
/// `"path:LINE: message"`. `interrupt` is asked after every chunk whether to stop.
pub fn read_obj(path: &Path, options: &ReadOptions, interrupt: Interrupt<'_>) -> Result<ObjMesh> {
    let name = path.display().to_string();
    let io_error = |e: std::io::Error| Error::Io(format!("{name}: {e}"));
    let mut file = File::open(path).map_err(io_error)?;
    let metadata = file.metadata().map_err(io_error)?;
    if metadata.is_dir() {
        return Err(Error::Io(format!("{name}: is a directory")));
    }
    let too_large = |size: String| {
        Error::Io(format!(
            "{name}: {size} bytes, larger than the input limit of {} bytes",
            options.max_bytes
        ))
    };
    // A regular file is refused before anything is read; devices and pipes are counted.
    if metadata.is_file() && metadata.len() > options.max_bytes {
        return Err(too_large(metadata.len().to_string()));
    }
    let mut parser = Parser::new(&name, options.memory_budget);
    let mut lines = Lines::default();
    let mut chunk = vec![0u8; CHUNK_BYTES];
    let mut total: u64 = 0;
    loop {
        let n = match file.read(&mut chunk) {
            Ok(0) => break,
            Ok(n) => n,
            Err(e) if e.kind() == std::io::ErrorKind::Interrupted => continue,
            Err(e) => return Err(io_error(e)),
        };
        total += n as u64;
        if total > options.max_bytes {
            return Err(too_large(format!("more than {}", options.max_bytes)));
        }
        parser.make_room(n)?;
        lines.feed(&chunk[..n], &mut parser)?;
        parser.check_memory(lines.line)?;
        interrupt()?;
    }
    lines.finish(&mut parser)?;
    parser.finish()
}

/// Parses OBJ text (see [`read_obj`]); errors are reported as `"<obj>:LINE: message"`. The
/// memory budget is the default one.
pub fn parse_obj(text: &str) -> Result<ObjMesh> {
    let mut parser = Parser::new("<obj>", default_memory_budget());
    let mut lines = Lines::default();
    parser.make_room(text.len())?;
    lines.feed(text.as_bytes(), &mut parser)?;
    lines.finish(&mut parser)?;
    parser.finish()
}

/// Splits a byte stream fed in pieces into lines (LF, CRLF or CR), numbered from 1; joins
/// lines ending in a backslash with the next (OBJ continuation lines).
#[derive(Default)]
struct Lines {
    /// The start of a line whose end is in a later piece.
    partial: Vec<u8>,
    /// Number of the line being read (0 before the first byte).
    line: usize,
    /// The last piece ended with CR: an LF at the start of the next one belongs to it.
    after_cr: bool,
    /// A statement continued with a backslash, and the line it started on.
    joined: String,
    joined_start: usize,
}

impl Lines {
    fn feed(&mut self, mut bytes: &[u8], parser: &mut Parser<'_>) -> Result<()> {
        if self.after_cr && bytes.first() == Some(&b'\n') {
            bytes = &bytes[1..];
        }
        self.after_cr = false;
        while let Some(at) = bytes
            .iter()
            .position(|&b| b == b'\n' || b == b'\r' || b == 0)
        {
            if bytes[at] == 0 {
                return Err(parser.error(self.line + 1, "NUL byte: this is not an OBJ text file"));
            }
            let end = at;
            let mut next = at + 1;
            if bytes[at] == b'\r' {
                match bytes.get(next) {
                    Some(b'\n') => next += 1,
                    None => self.after_cr = true,
                    Some(_) => {}
                }
            }
            if self.partial.is_empty() {
                self.line(&bytes[..end], parser)?;
            } else {
                let mut whole = std::mem::take(&mut self.partial);
                memory::reserve(&mut whole, end)?;
                whole.extend_from_slice(&bytes[..end]);
                self.line(&whole, parser)?;
            }
            bytes = &bytes[next..];
        }
        memory::reserve(&mut self.partial, bytes.len())?;
        self.partial.extend_from_slice(bytes);
        Ok(())
    }

    fn finish(&mut self, parser: &mut Parser<'_>) -> Result<()> {
        if !self.partial.is_empty() {
            let last = std::mem::take(&mut self.partial);
            self.line(&last, parser)?;
        }
        if !self.joined.is_empty() {
            let statement = std::mem::take(&mut self.joined);
            parser.statement(&statement, self.joined_start)?;
        }
        Ok(())
    }

    fn line(&mut self, bytes: &[u8], parser: &mut Parser<'_>) -> Result<()> {
        self.line += 1;
        let mut bytes = bytes;
        if self.line == 1 {
            bytes = bytes.strip_prefix(b"\xEF\xBB\xBF").unwrap_or(bytes);
        }
        let text = String::from_utf8_lossy(bytes);
        let content = match text.find('#') {
            Some(pos) => &text[..pos],
            None => &text,
        };
        let trimmed = content.trim_end();
        if let Some(head) = trimmed.strip_suffix('\\') {
            if self.joined.is_empty() {
                self.joined_start = self.line;
            }
            self.joined.push_str(head);
            self.joined.push(' ');
            return Ok(());
        }
        if self.joined.is_empty() {
            parser.statement(trimmed, self.line)
        } else {
            self.joined.push_str(trimmed);
            let statement = std::mem::take(&mut self.joined);
            parser.statement(&statement, self.joined_start)
        }
    }
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

/// Statements of the OBJ format that carry nothing a subdivision cage needs: skipped silently.
const UNUSED_STATEMENTS: &[&str] = &[
    "vn",
    "vp",
    "g",
    "o",
    "s",
    "mg",
    "usemtl",
    "mtllib",
    "l",
    "p",
    "lod",
    "bevel",
    "c_interp",
    "d_interp",
    "shadow_obj",
    "trace_obj",
    "maplib",
    "usemap",
];

/// Free-form geometry statements of the OBJ format: not supported, warned about.
const FREE_FORM_STATEMENTS: &[&str] = &[
    "cstype", "deg", "bmat", "step", "curv", "curv2", "surf", "parm", "trim", "hole", "scrv", "sp",
    "end", "con", "ctech", "stech",
];

/// Something ignored, counted per kind for one warning each.
struct Ignored {
    first_line: usize,
    count: usize,
}

struct Parser<'a> {
    name: &'a str,
    memory_budget: u64,
    mesh: ObjMesh,
    /// Texture coordinate of each corner so far, while every corner has one.
    face_uvs: Vec<i64>,
    /// Some corner has no texture coordinate (so the mesh has no face-varying uvs).
    corner_without_uv: bool,
    pending: Vec<Pending>,
    /// Ignored statements and tags by description, in the order first seen.
    ignored: Vec<(String, Ignored)>,
    ignored_index: HashMap<String, usize>,
}

/// A syntax error message, before the file name and line are added.
type LineResult<T> = std::result::Result<T, String>;

impl<'a> Parser<'a> {
    fn new(name: &'a str, memory_budget: u64) -> Self {
        Parser {
            name,
            memory_budget,
            mesh: ObjMesh::default(),
            face_uvs: Vec::new(),
            corner_without_uv: false,
            pending: Vec::new(),
            ignored: Vec::new(),
            ignored_index: HashMap::new(),
        }
    }

    fn error(&self, line: usize, message: impl std::fmt::Display) -> Error {
        Error::Io(format!("{}:{line}: {message}", self.name))
    }

    /// Bytes held by the mesh being built.
    fn bytes(&self) -> u64 {
        let m = &self.mesh;
        let size = |n: usize, item: usize| (n * item) as u64;
        size(m.points.capacity(), 8)
            + size(m.face_sizes.capacity(), 8)
            + size(m.face_vertices.capacity(), 8)
            + size(m.uvs.capacity(), 8)
            + size(self.face_uvs.capacity(), 8)
            + size(m.source.face_lines.capacity(), 8)
            + size(m.creases.capacity(), 24 + 8)
            + size(m.corners.capacity(), 16 + 8)
            + size(self.pending.capacity(), std::mem::size_of::<Pending>())
    }

    /// Room in the mesh's large vectors for all that `bytes` of input can add (each point,
    /// index or face takes at least two bytes of text), so that their pushes do not reallocate
    /// past one chunk's worth: the vectors in use grow here, fallibly, by doubling (an empty
    /// one grows in its first chunk, by at most that chunk's size).
    fn make_room(&mut self, bytes: usize) -> Result<()> {
        fn room<T>(v: &mut Vec<T>, most: usize) -> Result<()> {
            if !v.is_empty() && v.capacity() - v.len() < most {
                memory::reserve(v, most.max(v.len()))?;
            }
            Ok(())
        }
        let most = bytes / 2 + 1;
        let m = &mut self.mesh;
        room(&mut m.points, most)?;
        room(&mut m.uvs, most)?;
        room(&mut m.face_vertices, most)?;
        room(&mut m.face_sizes, most)?;
        room(&mut m.source.face_lines, most)?;
        room(&mut self.face_uvs, most)?;
        Ok(())
    }

    fn check_memory(&self, line: usize) -> Result<()> {
        let required = self.bytes();
        if required > self.memory_budget {
            return Err(Error::InFile {
                message: format!(
                    "{}:{line}: the mesh read so far takes {required} bytes, over the memory \
                     budget of {} bytes",
                    self.name, self.memory_budget
                ),
                line: Some(line),
                error: Box::new(Error::MemoryBudget {
                    required,
                    budget: self.memory_budget,
                    faces: self.mesh.face_sizes.len() as u64,
                }),
            });
        }
        Ok(())
    }

    /// Counts one ignored item of kind `what` (one warning per kind).
    fn ignore(&mut self, what: String, line: usize) {
        match self.ignored_index.get(&what) {
            Some(&i) => self.ignored[i].1.count += 1,
            None => {
                self.ignored_index.insert(what.clone(), self.ignored.len());
                self.ignored.push((
                    what,
                    Ignored {
                        first_line: line,
                        count: 1,
                    },
                ));
            }
        }
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
            _ if UNUSED_STATEMENTS.contains(&keyword) => Ok(()),
            _ if FREE_FORM_STATEMENTS.contains(&keyword) => {
                self.ignore(
                    format!(
                        "free-form geometry ('{}') is not supported and was ignored",
                        shown(keyword)
                    ),
                    line,
                );
                Ok(())
            }
            _ => {
                self.ignore(
                    format!("unknown statement '{}' was ignored", shown(keyword)),
                    line,
                );
                Ok(())
            }
        };
        outcome.map_err(|message| self.error(line, message))
    }

    fn vertex<'t>(&mut self, mut tokens: impl Iterator<Item = &'t str>) -> LineResult<()> {
        for axis in ["x", "y", "z"] {
            let token = tokens
                .next()
                .ok_or_else(|| format!("'v' needs 3 coordinates, {axis} is missing"))?;
            self.mesh.points.push(parse_finite(token)?);
        }
        // A weight w, or vertex colours r g b (with or without w), may follow: not used, but
        // they must be numbers (anything else is a damaged line).
        let mut extra = 0;
        for token in tokens {
            parse_f64(token).map_err(|_| {
                format!(
                    "'{}' after the coordinates: a 'v' line holds x y z, then optionally w or r g b",
                    shown(token)
                )
            })?;
            extra += 1;
        }
        if ![0, 1, 3, 4].contains(&extra) {
            return Err(format!(
                "'v' has {} numbers: it holds x y z, then optionally w or r g b",
                3 + extra
            ));
        }
        Ok(())
    }

    fn texture<'t>(&mut self, mut tokens: impl Iterator<Item = &'t str>) -> LineResult<()> {
        let u = tokens
            .next()
            .ok_or_else(|| "'vt' needs at least 1 coordinate".to_string())?;
        let u = parse_finite(u)?;
        let v = match tokens.next() {
            Some(token) => parse_finite(token)?,
            None => 0.0,
        };
        // An optional w, not used.
        if let Some(w) = tokens.next() {
            parse_f64(w)?;
        }
        if let Some(extra) = tokens.next() {
            return Err(format!(
                "'{}' after the coordinates: a 'vt' line holds u, then optionally v and w",
                shown(extra)
            ));
        }
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
                    "bad face corner '{}' (forms: v, v/vt, v//vn, v/vt/vn)",
                    shown(token)
                ));
            }
            if vertex.is_empty() {
                return Err(format!(
                    "bad face corner '{}': no vertex index",
                    shown(token)
                ));
            }
            let v = self.resolve(vertex, num_vertices, line, PendingKind::Vertex)?;
            self.mesh.face_vertices.push(v);
            match uv {
                Some(uv) if !uv.is_empty() => {
                    let t = self.resolve(uv, num_uvs, line, PendingKind::Uv)?;
                    if !self.corner_without_uv {
                        self.face_uvs.push(t);
                    }
                }
                _ => {
                    // The uvs are face-varying only if every corner has one: stop collecting.
                    self.corner_without_uv = true;
                    self.face_uvs = Vec::new();
                }
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
        self.mesh.source.face_lines.push(line);
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
        let name = shown(name);
        let name = name.as_str();
        let counts = tokens
            .next()
            .ok_or_else(|| format!("tag '{name}' needs argument counts (ints/floats/strings)"))?;
        let counts: Vec<&str> = counts.split('/').collect();
        let parse_count = |s: &str| {
            s.parse::<usize>().map_err(|_| {
                format!(
                    "tag '{name}': bad argument counts '{}'",
                    shown(&counts.join("/"))
                )
            })
        };
        if counts.len() != 3 {
            return Err(format!(
                "tag '{name}': argument counts must look like ints/floats/strings, got '{}'",
                shown(&counts.join("/"))
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
        let strings = &args[num_ints + num_floats..];
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
                    self.mesh.source.crease_lines.push(line);
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
                    self.mesh.source.corner_lines.push(line);
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
            "creasemethod" => {
                if num_ints != 0 || num_floats != 0 || strings.len() != 1 {
                    return Err(format!(
                        "tag 'creasemethod' needs exactly 1 string (normal or chaikin), got \
                         {num_ints}/{num_floats}/{num_strings}"
                    ));
                }
                // OpenSubdiv's shape files call the uniform method "normal".
                self.mesh.creasing = Some(match strings[0] {
                    "normal" | "uniform" => Creasing::Uniform,
                    "chaikin" => Creasing::Chaikin,
                    other => {
                        return Err(format!(
                            "unknown creasemethod '{}' (normal or chaikin)",
                            shown(other)
                        ))
                    }
                });
            }
            // Other OpenSubdiv tags (hole, smoothtriangles, facevaryinginterpolateboundary,
            // ...) change OpenSubdiv's surface in ways this scheme does not follow.
            other => {
                self.ignore(
                    format!("tag '{other}' is not supported and was ignored"),
                    line,
                );
            }
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
        if !self.corner_without_uv && !self.face_uvs.is_empty() {
            self.mesh.face_uvs = Some(std::mem::take(&mut self.face_uvs));
        }
        for (what, ignored) in &self.ignored {
            let times = match ignored.count {
                1 => String::new(),
                n => format!(" ({n} times)"),
            };
            self.mesh.warnings.push(format!(
                "{}:{}: {what}{times}",
                self.name, ignored.first_line
            ));
        }
        self.mesh.source.name = self.name.to_string();
        Ok(self.mesh)
    }
}

/// A token of the file as a message shows it: control characters escaped (a file cannot write
/// to the user's terminal through an error), at most 40 characters.
fn shown(token: &str) -> String {
    let mut text: String = token
        .chars()
        .take(40)
        .flat_map(char::escape_debug)
        .collect();
    if token.chars().nth(40).is_some() {
        text.push_str("...");
    }
    text
}

fn parse_f64(token: &str) -> LineResult<f64> {
    token
        .parse::<f64>()
        .map_err(|_| format!("'{}' is not a number", shown(token)))
}

/// A coordinate: a number, and finite (`nan`, `inf` and `1e999` parse as numbers).
fn parse_finite(token: &str) -> LineResult<f64> {
    let x = parse_f64(token)?;
    if !x.is_finite() {
        return Err(format!("'{}' is not a finite number", shown(token)));
    }
    Ok(x)
}

fn parse_index(token: &str) -> LineResult<i64> {
    token
        .parse::<i64>()
        .map_err(|_| format!("'{}' is not an integer index", shown(token)))
}

fn parse_sharpness(token: &str) -> LineResult<f32> {
    let s = token
        .parse::<f32>()
        .map_err(|_| format!("'{}' is not a sharpness value", shown(token)))?;
    if s.is_nan() || s < 0.0 {
        return Err(format!("sharpness {} must be a number >= 0", shown(token)));
    }
    Ok(s)
}

/// Where the elements of an [`ObjMesh`] are in its file: the line of each face, crease and
/// corner (in the order of the mesh's arrays), to restate errors about the mesh in the file's
/// own terms.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct ObjSource {
    /// The file's name as given (`<obj>` for [`parse_obj`]).
    pub name: String,
    /// Line of each face's `f` statement.
    pub face_lines: Vec<usize>,
    /// Line of the `t crease` tag of each crease.
    pub crease_lines: Vec<usize>,
    /// Line of the `t corner` tag of each corner.
    pub corner_lines: Vec<usize>,
}

impl ObjSource {
    /// `error`, found in a mesh built from this file (`cage`, in the same order, when it could be
    /// built), restated in the file's terms: `"path:LINE: message"` with the line of the
    /// element and 1-based OBJ vertex indices (tag indices stay 0-based, as tags write them), as
    /// [`Error::InFile`] around the original. Errors that concern no element of the file are
    /// returned unchanged.
    pub fn restate(&self, error: Error, cage: Option<&Cage>) -> Error {
        let face = |f: usize| self.face_lines.get(f).copied();
        let (line, text) = match &error {
            Error::RepeatedVertex { face: f, vertex } => (
                face(*f),
                format!("the face uses vertex {} more than once", vertex + 1),
            ),
            Error::FaceTooSmall { face: f, size } => (
                face(*f),
                format!("the face has {size} vertices; faces need at least 3"),
            ),
            Error::DegenerateFace { face: f } => {
                (face(*f), "the face is degenerate (zero area)".to_string())
            }
            Error::InconsistentOrientation {
                a,
                b,
                face_a,
                face_b,
            } => {
                let other = face(*face_a).map_or(String::new(), |l| format!(" at line {l}"));
                (
                    face(*face_b),
                    format!(
                        "this face and the face{other} have opposite orientations (both run \
                         the edge from vertex {} to vertex {} the same way)",
                        a + 1,
                        b + 1
                    ),
                )
            }
            Error::NonManifoldEdge { a, b, faces } => {
                let lines = self.lines_of_edge(cage, *a as u32, *b as u32);
                let listed = match lines.is_empty() {
                    true => String::new(),
                    false => {
                        let numbers: Vec<String> = lines.iter().map(|l| l.to_string()).collect();
                        format!(" (lines {})", numbers.join(", "))
                    }
                };
                (
                    lines.first().copied(),
                    format!(
                        "the edge between vertices {} and {} is shared by {faces} \
                         faces{listed}; the mesh must be a 2-manifold",
                        a + 1,
                        b + 1
                    ),
                )
            }
            Error::CreaseNotAnEdge { crease, a, b } => (
                self.crease_lines.get(*crease).copied(),
                format!("crease ({a}, {b}) is not an edge of the mesh"),
            ),
            Error::NonFinite { vertex } => (
                None,
                format!("vertex {} has a non-finite coordinate", vertex + 1),
            ),
            Error::EmptyMesh(_) => (None, error.to_string()),
            _ => return error,
        };
        let message = match line {
            Some(line) => format!("{}:{line}: {text}", self.name),
            None => format!("{}: {text}", self.name),
        };
        Error::InFile {
            message,
            line,
            error: Box::new(error),
        }
    }

    /// Lines of the faces that have the edge `a`-`b`.
    fn lines_of_edge(&self, cage: Option<&Cage>, a: u32, b: u32) -> Vec<usize> {
        let Some(cage) = cage else {
            return Vec::new();
        };
        let offsets = cage.face_offsets();
        let verts = cage.face_vertices();
        (0..cage.num_faces())
            .filter(|&f| {
                let fv = &verts[offsets[f] as usize..offsets[f + 1] as usize];
                (0..fv.len()).any(|i| {
                    let (p, q) = (fv[i], fv[(i + 1) % fv.len()]);
                    (p, q) == (a, b) || (p, q) == (b, a)
                })
            })
            .filter_map(|f| self.face_lines.get(f).copied())
            .collect()
    }
}
