//! The glTF and OBJ importers refusing what they cannot load truthfully: malformed and missing
//! files, unsupported required extensions, corrupt accessors and images, NaN positions, node
//! graphs that are not trees. Each refusal is one line naming the file.

mod common;

use common::gltf::{corrupt_quad, default_material, quad_gltf, write_gltf};
use rtd::scene::{load_scene, AccessorProblem, SceneError};
use serde_json::json;

#[test]
fn unsupported_required_extension_is_named() {
    let dir = tempfile::tempdir().unwrap();
    let (doc, buf) = quad_gltf(
        json!([{"mesh": 0}]),
        default_material(),
        &[
            ("extensionsUsed", json!(["KHR_draco_mesh_compression"])),
            ("extensionsRequired", json!(["KHR_draco_mesh_compression"])),
        ],
    );
    let p = write_gltf(dir.path(), "draco.gltf", doc, &buf);
    let e = load_scene(&p).unwrap_err().to_string();
    assert!(e.contains("KHR_draco_mesh_compression") && e.contains("draco.gltf"), "{e}");
    assert!(!e.contains('\n'));
}

#[test]
fn malformed_files_are_errors_naming_the_file() {
    let dir = tempfile::tempdir().unwrap();
    for (name, body) in [("bad.gltf", &b"{ not json"[..]), ("bad.glb", b"glTF\x02\0\0\0garbage"), ("empty.gltf", b"")] {
        let p = dir.path().join(name);
        std::fs::write(&p, body).unwrap();
        let e = load_scene(&p).unwrap_err().to_string();
        assert!(e.contains(name) && !e.contains('\n'), "{e}");
    }
    // A buffer too short for its accessors.
    let (doc, buf) = quad_gltf(json!([{"mesh": 0}]), default_material(), &[]);
    let p = write_gltf(dir.path(), "short.gltf", doc, &buf[..20]);
    assert!(load_scene(&p).unwrap_err().to_string().contains("short.gltf"));
    assert!(load_scene(&dir.path().join("missing.gltf")).is_err());
    assert!(load_scene(&dir.path().join("scene.fbx")).unwrap_err().to_string().contains("unknown scene format"));
}

#[test]
fn a_missing_file_reads_no_such_file_in_every_format() {
    let dir = tempfile::tempdir().unwrap();
    for name in ["missing.gltf", "missing.glb", "missing.obj", "MISSING.GLTF"] {
        let p = dir.path().join(name);
        let e = load_scene(&p).unwrap_err();
        assert_eq!(e.to_string(), format!("{}: no such file", p.display()));
        assert_eq!(e.path(), p.as_path());
        match &e {
            SceneError::Io { source, .. } => assert_eq!(source.kind(), std::io::ErrorKind::NotFound),
            other => panic!("{name}: expected an I/O error, got {other:?}"),
        }
        assert!(std::error::Error::source(&e).is_some(), "the io::Error is kept as the source");
    }
    // The extension decides before the file is looked at.
    let e = load_scene(&dir.path().join("missing.fbx")).unwrap_err();
    assert!(matches!(e, SceneError::UnknownFormat { .. }), "{e:?}");
}

#[test]
fn an_accessor_running_past_its_buffer_view_is_an_error_naming_file_mesh_and_accessor() {
    let dir = tempfile::tempdir().unwrap();
    let (p, e) = corrupt_quad(dir.path(), "scene.gltf", |doc, _| {
        doc["meshes"][0]["name"] = json!("Cube");
        doc["accessors"][0]["count"] = json!(1_000_000_000u64);
    });
    assert_eq!(
        e.to_string(),
        format!(
            "{}: mesh 0 (\"Cube\"), accessor 0: 1000000000 elements of 12 bytes run past the end of buffer view 0 \
             (48 bytes)",
            p.display()
        )
    );
    match e {
        SceneError::Accessor { mesh, mesh_name, accessor, problem, .. } => {
            assert_eq!((mesh, mesh_name.as_deref(), accessor), (0, Some("Cube"), 0));
            assert!(matches!(*problem, AccessorProblem::PastViewEnd { count: 1_000_000_000, view: 0, .. }));
        }
        other => panic!("expected an accessor error, got {other:?}"),
    }
    // The indices (accessor 2) one element too long for their view; the mesh has no name.
    let (p, e) = corrupt_quad(dir.path(), "indices.gltf", |doc, _| doc["accessors"][2]["count"] = json!(7));
    assert_eq!(
        e.to_string(),
        format!(
            "{}: mesh 0, accessor 2: 7 elements of 2 bytes run past the end of buffer view 2 (12 bytes)",
            p.display()
        )
    );
    // A stride wider than the view allows for four elements.
    let (_, e) = corrupt_quad(dir.path(), "stride.gltf", |doc, _| doc["bufferViews"][1]["byteStride"] = json!(12));
    let expected = "accessor 1: 4 elements of 8 bytes with stride 12 run past the end of buffer view 1 (32 bytes)";
    assert!(e.to_string().ends_with(expected), "{e}");
}

#[test]
fn an_image_that_cannot_be_decoded_is_named_in_the_error() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("wood.png"), b"\x89PNG\r\n\x1a\nnot a png at all").unwrap();
    let (p, e) = corrupt_quad(dir.path(), "images.gltf", |doc, _| {
        doc["images"] = json!([{"uri": "data:image/png;base64,iVBORw0KGgo="}, {"uri": "wood.png", "name": "Wood"}]);
    });
    let text = e.to_string();
    assert!(text.starts_with(&format!("{}: cannot load image ", p.display())), "{text}");
    // The first image (a truncated PNG in a data URI) fails first, then, once fixed, the second.
    assert!(text.contains("image 0 (embedded data)"), "{text}");
    let (_, e) = corrupt_quad(dir.path(), "images2.gltf", |doc, _| {
        doc["images"] = json!([{"uri": "wood.png", "name": "Wood"}]);
    });
    assert!(e.to_string().contains("cannot load image 0 (\"Wood\", \"wood.png\")"), "{e}");
    assert!(matches!(e, SceneError::GltfImage { .. }), "{e:?}");
}

#[test]
fn a_texture_over_rtds_pixel_limit_is_refused_before_it_is_widened() {
    // 16384 x 4097 is one row of 16384 over MAX_PIXELS (2^26), and 67 MB as 8-bit grey: well
    // inside the image decoder's own 512 MiB bound, so only rtd's limit can refuse it.
    let (w, h) = (16384, 4097);
    assert!(w * h > rtd::image::MAX_PIXELS && w * h - w <= rtd::image::MAX_PIXELS);
    let dir = tempfile::tempdir().unwrap();
    let file = std::fs::File::create(dir.path().join("big.png")).unwrap();
    let png = image::codecs::png::PngEncoder::new_with_quality(
        std::io::BufWriter::new(file),
        image::codecs::png::CompressionType::Fast,
        image::codecs::png::FilterType::NoFilter,
    );
    image::ImageEncoder::write_image(png, &vec![0u8; w * h], w as u32, h as u32, image::ExtendedColorType::L8).unwrap();
    let (p, e) = corrupt_quad(dir.path(), "big.gltf", |doc, _| doc["images"] = json!([{"uri": "big.png"}]));
    assert_eq!(
        e.to_string(),
        format!(
            "{}: image 0 (\"big.png\"): image size 16384x4097 exceeds {} pixels",
            p.display(),
            rtd::image::MAX_PIXELS
        )
    );
}

#[test]
fn nan_or_infinite_positions_fail_the_load_and_name_the_file() {
    let dir = tempfile::tempdir().unwrap();
    // Vertex 0 (in both triangles of the quad) made NaN.
    let (p, e) = corrupt_quad(dir.path(), "nan.gltf", |_, buf| buf[0..4].copy_from_slice(&f32::NAN.to_le_bytes()));
    assert_eq!(e.to_string(), format!("{}: 2 triangles have NaN or infinite vertex positions", p.display()));
    // Finite in the file and a finite transform, but x = 1 lands at 3e38 + 3e38 = infinity.
    let (p, e) = corrupt_quad(dir.path(), "far.gltf", |doc, _| {
        doc["nodes"][0]["scale"] = json!([3e38, 1, 1]);
        doc["nodes"][0]["translation"] = json!([3e38, 0, 0]);
    });
    assert_eq!(e.to_string(), format!("{}: 2 triangles have NaN or infinite vertex positions", p.display()));
    // A transform that is itself past f32's range refuses everything under it.
    let (p, e) = corrupt_quad(dir.path(), "huge.gltf", |doc, _| {
        doc["nodes"][0]["name"] = json!("Big");
        doc["nodes"][0]["scale"] = json!([1e39, 1e39, 1e39]);
    });
    assert_eq!(
        e.to_string(),
        format!("{}: node 0 (\"Big\") has a non-finite transform (NaN, or past f32's range)", p.display())
    );
}

#[test]
fn a_node_graph_that_is_not_a_tree_is_refused_rather_than_walked_for_ever() {
    let dir = tempfile::tempdir().unwrap();
    let cases = [
        ("self.gltf", json!([{"mesh": 0, "children": [0]}]), 0),
        ("loop.gltf", json!([{"mesh": 0, "children": [1]}, {"children": [0]}]), 0),
        ("shared.gltf", json!([{"children": [1, 1]}, {"mesh": 0}]), 1),
    ];
    for (name, nodes, twice) in cases {
        let (p, e) = corrupt_quad(dir.path(), name, |doc, _| doc["nodes"] = nodes);
        let want =
            format!("{}: node {twice} has two parents or lies in a cycle: glTF nodes must form trees", p.display());
        assert_eq!(e.to_string(), want);
    }
}

#[test]
fn an_obj_texture_of_zero_size_is_a_warning_not_a_panic() {
    let dir = tempfile::tempdir().unwrap();
    // A Radiance header the image crate accepts, declaring 5 x 0 pixels.
    std::fs::write(dir.path().join("t.hdr"), b"#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n-Y 0 +X 5\n").unwrap();
    std::fs::write(dir.path().join("m.mtl"), "newmtl a\nKd 1 1 1\nmap_Kd t.hdr\n").unwrap();
    std::fs::write(dir.path().join("m.obj"), "mtllib m.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nusemtl a\nf 1 2 3\n").unwrap();
    let s = load_scene(&dir.path().join("m.obj")).unwrap();
    assert!(s.textures.is_empty());
    let t = dir.path().join("t.hdr");
    let want = format!("material a: texture not loaded: {}: image size 5x0 is outside 1..=16384 a side", t.display());
    assert_eq!(s.warnings, [want]);
}

#[test]
fn other_structural_corruption_is_an_error_too() {
    let dir = tempfile::tempdir().unwrap();
    // An index naming vertex 7 of a 4-vertex quad.
    let (p, e) = corrupt_quad(dir.path(), "index.gltf", |_, buf| buf[90..92].copy_from_slice(&7u16.to_le_bytes()));
    assert_eq!(e.to_string(), format!("{}: mesh 0, accessor 2: index 7 is out of range (4 vertices)", p.display()));
    let problem = AccessorProblem::IndexOutOfRange { index: 7, vertex_count: 4 };
    assert!(matches!(e, SceneError::Accessor { accessor: 2, problem: ref found, .. } if **found == problem), "{e:?}");
    // A buffer view past the end of its buffer.
    let (p, e) = corrupt_quad(dir.path(), "view.gltf", |doc, _| doc["bufferViews"][2]["byteLength"] = json!(100));
    assert_eq!(
        e.to_string(),
        format!("{}: buffer view 2 (bytes 80..180) runs past the end of buffer 0 (92 bytes)", p.display())
    );
    // NORMAL pointing at the VEC2 texture coordinates.
    let (_, e) = corrupt_quad(dir.path(), "normal.gltf", |doc, _| {
        doc["meshes"][0]["primitives"][0]["attributes"]["NORMAL"] = json!(1);
    });
    assert!(e.to_string().ends_with("mesh 0, accessor 1: NORMAL is VEC2 of f32; rtd reads VEC3 of f32"), "{e}");
    // TEXCOORD_0 with fewer elements than POSITION.
    let (_, e) = corrupt_quad(dir.path(), "uv.gltf", |doc, _| doc["accessors"][1]["count"] = json!(3));
    assert!(e.to_string().ends_with("mesh 0, accessor 1: TEXCOORD_0 has 3 elements but POSITION has 4"), "{e}");
    // A count of zero.
    let (_, e) = corrupt_quad(dir.path(), "zero.gltf", |doc, _| doc["accessors"][2]["count"] = json!(0));
    assert!(e.to_string().ends_with("mesh 0, accessor 2: element count is 0"), "{e}");
}
