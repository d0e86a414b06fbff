//! Tests of OBJ reading and writing.

use super::*;
use crate::error::Error;

/// Reads with the default limits.
fn read(path: &std::path::Path) -> Result<ObjMesh> {
    read_obj(path, &ReadOptions::default(), UNINTERRUPTED)
}

/// Writes with optional indexed uvs and per-corner normals.
fn write<T: ObjFloat>(
    path: &std::path::Path,
    points: &[T],
    face_offsets: &[u32],
    face_vertices: &[u32],
    uvs: Option<(&[T], &[u32])>,
    normals: Option<&[T]>,
) -> Result<()> {
    let mesh = ObjOutput {
        points,
        face_offsets,
        face_vertices,
        uvs: uvs.map(|(values, indices)| Uvs::Indexed { values, indices }),
        normals,
    };
    write_obj(path, &mesh, UNINTERRUPTED)
}

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
        parse_obj("v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nvt 0 0\nf 1/1 2/1 3/1\nf 1 3 4\n").unwrap();
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
            "t hole 1/0/0 -1\n",
            "<obj>:1: tag hole face index -1 is negative",
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
        // Trailing garbage, non-finite numbers, bad creasemethod tags, binary data.
        (
            "v 1 2 3 garbage\n",
            "<obj>:1: 'garbage' after the coordinates",
        ),
        ("v 0 0 0\nv 1 2 3 4 5\n", "<obj>:2: 'v' has 5 numbers"),
        ("v 1 2 3 1 2 3 4 5\n", "<obj>:1: 'v' has 8 numbers"),
        ("vt 0 0 0 9\n", "<obj>:1: '9' after the coordinates"),
        ("vt 0 x\n", "<obj>:1: 'x' is not a number"),
        ("v nan 0 0\n", "<obj>:1: 'nan' is not a finite number"),
        ("v 0 inf 0\n", "<obj>:1: 'inf' is not a finite number"),
        ("v 0 0 1e999\n", "<obj>:1: '1e999' is not a finite number"),
        ("vt NaN 0\n", "<obj>:1: 'NaN' is not a finite number"),
        (
            "v 0 0 0\nv 1 0 0\nv 1 1 0\nf 1 2 3 trailing\n",
            "<obj>:4: 'trailing' is not an integer index",
        ),
        (
            "t creasemethod 0/0/1 fancy\n",
            "<obj>:1: unknown creasemethod 'fancy'",
        ),
        (
            "t creasemethod 1/0/0 1\n",
            "<obj>:1: tag 'creasemethod' needs exactly 1 string",
        ),
        ("v 0 0 0\nv\x001 0 0\n", "<obj>:2: NUL byte"),
        // Control characters are escaped, long tokens cut: a file cannot write to a terminal.
        ("v 0 0 \x1b[2J\n", "<obj>:1: '\\u{1b}[2J' is not a number"),
        (
            "v 0 0 0 0123456789012345678901234567890123456789xyz\n",
            "<obj>:1: '0123456789012345678901234567890123456789...' after",
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
    match read(&path) {
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
    match read(&missing) {
        Err(Error::Io(message)) => {
            assert!(message.starts_with(&format!("{}: ", missing.display())))
        }
        other => panic!("{other:?}"),
    }
    // Latin-1 bytes in a comment do not stop the reader.
    std::fs::write(&path, b"# caf\xe9\nv 0 0 0\nv 1 0 0\nv 1 1 0\nf 1 2 3\n").unwrap();
    assert_eq!(read(&path).unwrap().num_faces(), 1);
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
    write(
        &path,
        &points,
        &offsets,
        &vertices,
        Some((&uv_values, &uv_indices)),
        None,
    )
    .unwrap();
    let mesh = read(&path).unwrap();
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

    write(&path, &points, &offsets, &vertices, None, None).unwrap();
    let mesh = read(&path).unwrap();
    assert_eq!(mesh.face_uvs, None);
    assert!(mesh.uvs.is_empty());
}

#[test]
fn normals_are_written_per_corner() {
    let path = temp_path("normals.obj");
    let points = [0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0];
    let normals = [0.0, 0.0, 1.0, 0.0, 0.6, 0.8, 0.0, 0.0, 1.0];
    write(&path, &points, &[0, 3], &[0, 1, 2], None, Some(&normals)).unwrap();
    let text = std::fs::read_to_string(&path).unwrap();
    assert!(text.contains("\nvn 0 0.6 0.8\n"), "{text}");
    assert!(text.contains("\nf 1//1 2//2 3//3\n"), "{text}");
    let uv = [0.0, 0.0, 1.0, 0.0, 0.0, 1.0];
    let uvs = Some((&uv[..], &[0u32, 1, 2][..]));
    write(&path, &points, &[0, 3], &[0, 1, 2], uvs, Some(&normals)).unwrap();
    let text = std::fs::read_to_string(&path).unwrap();
    assert!(text.contains("\nf 1/1/1 2/2/2 3/3/3\n"), "{text}");
    assert_eq!(read(&path).unwrap().points, points);
    assert!(matches!(
        write(
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
    write(
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
    let mesh = read(&path).unwrap();
    assert_eq!(mesh.points[0] as f32, 0.1f32);
}

#[test]
fn write_many_chunks_in_order() {
    // More vertices and faces than one batch, so chunks and batches are both exercised.
    let n = write::CHUNK_ITEMS * write::CHUNKS_PER_BATCH + write::CHUNK_ITEMS * 3 + 17;
    let points: Vec<f64> = (0..3 * n).map(|i| i as f64).collect();
    let offsets: Vec<u32> = (0..=n as u32).map(|f| 3 * f).collect();
    let vertices: Vec<u32> = (0..3 * n as u32)
        .map(|c| (c / 3 + c % 3) % n as u32)
        .collect();
    let path = temp_path("large.obj");
    write(&path, &points, &offsets, &vertices, None, None).unwrap();
    let mesh = read(&path).unwrap();
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
                write(&path, p, o, v, None, None),
                Err(Error::InvalidInput(_))
            ),
            "{o:?} {v:?}"
        );
    }
    let uv = [0.0; 4];
    assert!(matches!(
        write(
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
        write(
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
        write(&unwritable, &points, &[0, 3], &[0, 1, 2], None, None),
        Err(Error::Io(_))
    ));
}

#[test]
fn empty_input_gives_an_empty_mesh() {
    let mesh = parse_obj("").unwrap();
    assert_eq!(mesh.num_vertices(), 0);
    assert_eq!(mesh.num_faces(), 0);
    let path = temp_path("empty.obj");
    write::<f64>(&path, &[], &[], &[], None, None).unwrap();
    assert_eq!(read(&path).unwrap().num_faces(), 0);
}

/// The same text through `parse_obj` and, in 7-byte reads, through `read_obj`.
fn parse_both(text: &str) -> ObjMesh {
    let parsed = parse_obj(text).unwrap();
    let path = temp_path("both.obj");
    std::fs::write(&path, text).unwrap();
    let read = read(&path).unwrap();
    assert_eq!(read.points, parsed.points);
    assert_eq!(read.face_vertices, parsed.face_vertices);
    assert_eq!(read.source.face_lines, parsed.source.face_lines);
    parsed
}

#[test]
fn line_ends_bom_and_chunk_boundaries() {
    let lf = "v 0 0 0\nv 1 0 0\nv 1 1 0\nf 1 2 3\n";
    for text in [
        lf.to_string(),
        lf.replace('\n', "\r\n"),
        lf.replace('\n', "\r"),
        format!("\u{feff}{lf}"),
        format!("\u{feff}{}", lf.replace('\n', "\r")),
        "v 0 0 0\rv 1 0 0\r\nv 1 1 0\nf 1 2 3".to_string(),
    ] {
        let mesh = parse_both(&text);
        assert_eq!(mesh.num_vertices(), 3, "{text:?}");
        assert_eq!(mesh.face_vertices, vec![0, 1, 2], "{text:?}");
        assert_eq!(mesh.source.face_lines, vec![4], "{text:?}");
        assert!(mesh.warnings.is_empty(), "{text:?}: {:?}", mesh.warnings);
    }
    // Errors count CR-only lines too.
    assert_eq!(
        io_message("v 0 0 0\rv 1 0 0\r\rf 1 2 x\r"),
        "<obj>:4: 'x' is not an integer index"
    );
    // A BOM anywhere but the start is an unknown statement, not skipped silently.
    let mesh = parse_obj("v 0 0 0\n\u{feff}v 1 0 0\n").unwrap();
    assert_eq!(mesh.num_vertices(), 1);
    assert_eq!(mesh.warnings.len(), 1);
}

#[test]
fn optional_vertex_values_are_accepted() {
    // Optional w, colours, and w with colours are fine.
    let mesh =
        parse_obj("v 1 2 3 1\nv 1 2 3 0.5 0.5 0.5\nv 1 2 3 1 0 0 0\nvt 0.5 0.5 0\n").unwrap();
    assert_eq!(mesh.num_vertices(), 3);
    assert_eq!(mesh.uvs, vec![0.5, 0.5]);
}

#[test]
fn unknown_statements_and_tags_warn_once_per_kind() {
    let mesh = parse_obj(
        "v 0 0 0\nv 1 0 0\nv 1 1 0\n\
         frobnicate 1\n\
         f 1 2 3\n\
         frobnicate 2\n\
         t hole 1/0/0 0\n\
         t smoothtriangles 0/0/1 smooth\n\
         t smoothtriangles 0/0/1 smooth\n\
         surf 0 1 0 1 1 2 3\n\
         vn 0 0 1\n\
         g group\n",
    )
    .unwrap();
    assert_eq!(mesh.holes, vec![0]);
    assert_eq!(
        mesh.warnings,
        vec![
            "<obj>:4: unknown statement 'frobnicate' was ignored (2 times)",
            "<obj>:8: tag 'smoothtriangles' is not supported and was ignored (2 times)",
            "<obj>:10: free-form geometry ('surf') is not supported and was ignored",
        ]
    );
}

#[test]
fn creasemethod_is_read() {
    let mesh = parse_obj("v 0 0 0\nt creasemethod 0/0/1 chaikin\n").unwrap();
    assert_eq!(mesh.creasing, Some(Creasing::Chaikin));
    let mesh = parse_obj("t creasemethod 0/0/1 normal\n").unwrap();
    assert_eq!(mesh.creasing, Some(Creasing::Uniform));
    assert_eq!(parse_obj("v 0 0 0\n").unwrap().creasing, None);
}

#[test]
fn source_lines_of_faces_creases_and_corners() {
    let mesh = parse_obj(
        "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\n\
         f 1 2 \\\n 3\n\
         # comment\n\
         f 1 3 4\n\
         t crease 4/1/0 0 1 1 2 2\n\
         t corner 1/1/0 3 1\n",
    )
    .unwrap();
    assert_eq!(mesh.source.face_lines, vec![5, 8]);
    assert_eq!(mesh.source.crease_lines, vec![9, 9]);
    assert_eq!(mesh.source.corner_lines, vec![10]);
    assert_eq!(mesh.source.name, "<obj>");
}

/// The error of building a cage and a plan from an OBJ text, restated in the file's terms.
fn cage_error(text: &str) -> Error {
    let mesh = parse_obj(text).unwrap();
    let cage =
        crate::Cage::from_indices(mesh.num_vertices(), &mesh.face_sizes, &mesh.face_vertices)
            .and_then(|cage| cage.with_creases(&mesh.creases));
    match cage {
        Err(error) => mesh.source.restate(error, None),
        Ok(cage) => match crate::Plan::new(&cage, &crate::Options::default()) {
            Ok(_) => panic!("{text:?} was accepted"),
            Err(error) => mesh.source.restate(error, Some(&cage)),
        },
    }
}

#[test]
fn mesh_errors_are_restated_in_the_files_terms() {
    let quad = "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv 0 0 1\n";
    // A face repeating a vertex is a cage (OpenSubdiv's degenerate edge), unless it has fewer
    // than three distinct vertices.
    let repeated = cage_error(&format!("{quad}f 1 2 3\nf 1 3 3 1\n"));
    assert_eq!(
        repeated.to_string(),
        "<obj>:7: the face uses vertex 3 more than once"
    );
    assert!(matches!(
        repeated.kind(),
        Error::RepeatedVertex { face: 1, vertex: 2 }
    ));
    assert!(matches!(repeated, Error::InFile { line: Some(7), .. }));

    let crease = cage_error(&format!("{quad}f 1 2 3\nt crease 2/1/0 0 3 1\n"));
    assert_eq!(
        crease.to_string(),
        "<obj>:7: crease (0, 3) is not an edge of the mesh"
    );
}

#[test]
fn non_manifold_and_flipped_faces_are_cages() {
    // Three faces on one edge, a flipped face, a face repeating a vertex: all subdivide.
    let text = "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 -1 0\nv 0 0 1\nf 1 2 3\nf 2 1 4\nf 1 2 5\n\
                f 4 3 5 5\nt hole 1/0/0 2\nt interpolateboundary 1/0/0 0\n";
    let mesh = parse_obj(text).unwrap();
    assert_eq!(mesh.boundary, Some(Boundary::None));
    let cage = crate::Cage::from_indices(5, &mesh.face_sizes, &mesh.face_vertices)
        .and_then(|cage| cage.with_holes(&mesh.holes))
        .unwrap();
    assert_eq!(cage.holes(), &[2]);
    assert!(crate::Plan::new(&cage, &crate::Options::default()).is_ok());
    // Errors about no element of the file pass through.
    let budget = Error::MemoryBudget {
        required: 1,
        budget: 0,
        faces: 1,
    };
    assert_eq!(mesh.source.restate(budget.clone(), Some(&cage)), budget);
}

#[test]
fn read_limits() {
    let path = temp_path("limits.obj");
    std::fs::write(&path, "v 0 0 0\nv 1 0 0\nv 1 1 0\nf 1 2 3\n").unwrap();
    let small = ReadOptions {
        max_bytes: 10,
        ..ReadOptions::default()
    };
    match read_obj(&path, &small, UNINTERRUPTED) {
        Err(Error::Io(message)) => assert!(
            message.ends_with(": 32 bytes, larger than the input limit of 10 bytes"),
            "{message}"
        ),
        other => panic!("{other:?}"),
    }
    let tight = ReadOptions {
        memory_budget: 30,
        ..ReadOptions::default()
    };
    match read_obj(&path, &tight, UNINTERRUPTED) {
        Err(error @ Error::InFile { .. }) => {
            assert!(matches!(
                error.kind(),
                Error::MemoryBudget { budget: 30, .. }
            ));
            assert!(error
                .to_string()
                .contains("over the memory budget of 30 bytes"));
        }
        other => panic!("{other:?}"),
    }
    let stop = || Err(Error::Interrupted("stop".into()));
    assert!(matches!(
        read_obj(&path, &ReadOptions::default(), &stop),
        Err(Error::Interrupted(_))
    ));
    let dir = temp_path("");
    assert!(matches!(read(&dir), Err(Error::Io(m)) if m.ends_with("is a directory")));
}

#[cfg(unix)]
#[test]
fn dev_zero_is_refused_at_its_first_byte() {
    let started = std::time::Instant::now();
    match read(std::path::Path::new("/dev/zero")) {
        Err(Error::Io(message)) => assert_eq!(
            message,
            "/dev/zero:1: NUL byte: this is not an OBJ text file"
        ),
        other => panic!("{other:?}"),
    }
    assert!(started.elapsed() < std::time::Duration::from_secs(5));
}

/// Files in the directory of `path` (to see that no temporary file is left).
fn siblings(path: &std::path::Path) -> Vec<String> {
    let mut names: Vec<String> = std::fs::read_dir(path.parent().unwrap())
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    names.sort();
    names
}

#[test]
fn writes_are_atomic() {
    let dir = temp_path("atomic");
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("out.obj");
    std::fs::write(&path, "previous").unwrap();
    let points = [0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0];
    // Refused input and an interrupted write leave the old file and nothing else.
    let bad = [0.0, 0.0, 0.0, 1.0, f64::NAN, 0.0, 0.0, 1.0, 0.0];
    assert!(matches!(
        write(&path, &bad, &[0, 3], &[0, 1, 2], None, None),
        Err(Error::NonFinite { vertex: 1 })
    ));
    let stop = || Err(Error::Interrupted("stop".into()));
    let mesh = ObjOutput {
        points: &points[..],
        face_offsets: &[0, 3],
        face_vertices: &[0, 1, 2],
        uvs: None,
        normals: None,
    };
    assert!(matches!(
        write_obj(&path, &mesh, &stop),
        Err(Error::Interrupted(_))
    ));
    assert_eq!(std::fs::read_to_string(&path).unwrap(), "previous");
    assert_eq!(siblings(&path), vec!["out.obj"]);
    // A complete write replaces it.
    write_obj(&path, &mesh, UNINTERRUPTED).unwrap();
    assert_eq!(read(&path).unwrap().points, points);
    assert_eq!(siblings(&path), vec!["out.obj"]);
    assert!(matches!(
        write(&dir, &points, &[0, 3], &[0, 1, 2], None, None),
        Err(Error::Io(m)) if m.ends_with("is a directory")
    ));
}

#[test]
fn per_corner_uvs_and_non_finite_attributes() {
    let path = temp_path("corner-uvs.obj");
    let points = [0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0];
    let uv = [0.0, 0.0, 1.0, 0.0, 0.0, 1.0];
    let mut mesh = ObjOutput {
        points: &points[..],
        face_offsets: &[0, 3],
        face_vertices: &[0, 1, 2],
        uvs: Some(Uvs::PerCorner(&uv[..])),
        normals: None,
    };
    write_obj(&path, &mesh, UNINTERRUPTED).unwrap();
    let read_back = read(&path).unwrap();
    assert_eq!(read_back.uvs, uv);
    assert_eq!(read_back.face_uvs, Some(vec![0, 1, 2]));
    let bad_uv = [0.0, 0.0, f64::INFINITY, 0.0, 0.0, 1.0];
    mesh.uvs = Some(Uvs::PerCorner(&bad_uv[..]));
    assert!(matches!(
        write_obj(&path, &mesh, UNINTERRUPTED),
        Err(Error::InvalidInput(m)) if m == "write_obj: uv 1 is not finite"
    ));
    mesh.uvs = Some(Uvs::PerCorner(&uv[..4]));
    assert!(matches!(
        write_obj(&path, &mesh, UNINTERRUPTED),
        Err(Error::InvalidInput(_))
    ));
}
