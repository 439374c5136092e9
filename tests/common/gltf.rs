//! Hand-made glTF files for the importer tests: a unit quad whose JSON and buffer a test can
//! edit, written as .gltf (buffer as a data URI) or .glb.

use std::path::{Path, PathBuf};

use rtd::scene::{load_scene, SceneError};
use serde_json::{json, Value};

/// Little-endian f32 bytes.
pub fn f32_bytes(v: &[f32]) -> Vec<u8> {
    v.iter().flat_map(|x| x.to_le_bytes()).collect()
}

pub fn b64(bytes: &[u8]) -> String {
    // Minimal base64 encoder for data URIs in test files.
    const T: &[u8; 64] = b"ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
    let mut out = String::new();
    for c in bytes.chunks(3) {
        let n = (c[0] as u32) << 16 | (*c.get(1).unwrap_or(&0) as u32) << 8 | *c.get(2).unwrap_or(&0) as u32;
        for i in 0..4 {
            if i <= c.len() {
                out.push(T[(n >> (18 - 6 * i) & 63) as usize] as char);
            } else {
                out.push('=');
            }
        }
    }
    out
}

/// A glTF document with one buffer holding a unit quad in z=0 (positions, uvs, indices).
/// Returns (json, buffer bytes).
pub fn quad_gltf(nodes: Value, materials: Value, extra: &[(&str, Value)]) -> (Value, Vec<u8>) {
    let pos = f32_bytes(&[0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 1.0, 1.0, 0.0, 0.0, 1.0, 0.0]);
    let uv = f32_bytes(&[0.0, 1.0, 1.0, 1.0, 1.0, 0.0, 0.0, 0.0]);
    let idx: Vec<u8> = [0u16, 1, 2, 0, 2, 3].iter().flat_map(|i| i.to_le_bytes()).collect();
    let mut buf = pos.clone();
    buf.extend(&uv);
    buf.extend(&idx);
    let mut doc = json!({
        "asset": {"version": "2.0"},
        "scene": 0,
        "scenes": [{"nodes": [0]}],
        "nodes": nodes,
        "meshes": [{"primitives": [{"attributes": {"POSITION": 0, "TEXCOORD_0": 1}, "indices": 2, "material": 0}]}],
        "materials": materials,
        "buffers": [{"byteLength": buf.len()}],
        "bufferViews": [
            {"buffer": 0, "byteOffset": 0, "byteLength": 48},
            {"buffer": 0, "byteOffset": 48, "byteLength": 32},
            {"buffer": 0, "byteOffset": 80, "byteLength": 12}
        ],
        "accessors": [
            {"bufferView": 0, "componentType": 5126, "count": 4, "type": "VEC3", "min": [0,0,0], "max": [1,1,0]},
            {"bufferView": 1, "componentType": 5126, "count": 4, "type": "VEC2"},
            {"bufferView": 2, "componentType": 5123, "count": 6, "type": "SCALAR"}
        ]
    });
    for (k, v) in extra {
        doc[*k] = v.clone();
    }
    (doc, buf)
}

/// Writes a .gltf with the buffer embedded as a data URI.
pub fn write_gltf(dir: &Path, name: &str, mut doc: Value, buf: &[u8]) -> PathBuf {
    doc["buffers"][0]["uri"] = json!(format!("data:application/octet-stream;base64,{}", b64(buf)));
    let p = dir.join(name);
    std::fs::write(&p, serde_json::to_string(&doc).unwrap()).unwrap();
    p
}

/// Writes a binary .glb: header, JSON chunk, BIN chunk.
pub fn write_glb(dir: &Path, name: &str, doc: Value, buf: &[u8]) -> PathBuf {
    let mut js = serde_json::to_vec(&doc).unwrap();
    while !js.len().is_multiple_of(4) {
        js.push(b' ');
    }
    let mut bin = buf.to_vec();
    while !bin.len().is_multiple_of(4) {
        bin.push(0);
    }
    let total = 12 + 8 + js.len() + 8 + bin.len();
    let mut out = Vec::new();
    out.extend(b"glTF");
    out.extend(2u32.to_le_bytes());
    out.extend((total as u32).to_le_bytes());
    out.extend((js.len() as u32).to_le_bytes());
    out.extend(b"JSON");
    out.extend(&js);
    out.extend((bin.len() as u32).to_le_bytes());
    out.extend(b"BIN\0");
    out.extend(&bin);
    let p = dir.join(name);
    std::fs::write(&p, out).unwrap();
    p
}

pub fn default_material() -> Value {
    json!([{"pbrMetallicRoughness": {"baseColorFactor": [0.5, 0.5, 0.5, 1.0]}}])
}

/// The quad with one change made to its JSON by `edit`, written as `name`; the load error.
pub fn corrupt_quad(dir: &Path, name: &str, edit: impl FnOnce(&mut Value, &mut Vec<u8>)) -> (PathBuf, SceneError) {
    let (mut doc, mut buf) = quad_gltf(json!([{"mesh": 0}]), default_material(), &[]);
    edit(&mut doc, &mut buf);
    let p = write_gltf(dir, name, doc, &buf);
    let e = load_scene(&p).expect_err("a corrupt file must be refused");
    let text = e.to_string();
    assert!(text.starts_with(&p.display().to_string()) && !text.contains('\n'), "{text}");
    (p, e)
}
