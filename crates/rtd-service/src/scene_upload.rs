//! The check an uploaded scene passes before it is queued: a glTF that holds everything it
//! needs. A scene that names a file (an external buffer or image, `../`, an absolute path)
//! is refused, since on a render node that would read the node's own disk; so is one needing
//! an extension rtd lacks, and one whose embedded image declares an oversized header.

use std::path::Path;

use base64::Engine;
use rtd_scene::SUPPORTED_GLTF_EXTENSIONS;

/// `glb` or `gltf`, for a scene whose bytes pass the check; else the reason, one sentence.
pub fn check_scene(bytes: &[u8]) -> Result<&'static str, String> {
    let format = if bytes.starts_with(b"glTF") {
        "glb"
    } else if bytes.iter().find(|b| !b.is_ascii_whitespace()) == Some(&b'{') {
        "gltf"
    } else {
        return Err("scene: is neither a .glb nor a .gltf file (judged by its bytes)".into());
    };
    // The gltf crate panics on some malformed files (found by fuzzing): fenced.
    let parse = |validate: bool| {
        rtd_image::contain_panic(|| match validate {
            true => gltf::Gltf::from_slice(bytes),
            false => gltf::Gltf::from_slice_without_validation(bytes),
        })
        .map_err(|e| format!("scene: {e}"))
    };
    let raw = parse(false)?.map_err(|e| format!("scene: malformed glTF: {e}"))?;
    if let Some(ext) = raw.document.extensions_required().find(|e| !SUPPORTED_GLTF_EXTENSIONS.contains(e)) {
        return Err(format!("scene: requires the glTF extension {ext}, which rtd does not support"));
    }
    let gltf = parse(true)?.map_err(|e| format!("scene: invalid glTF: {e}"))?;
    for buffer in gltf.document.buffers() {
        if let gltf::buffer::Source::Uri(uri) = buffer.source() {
            embedded(uri).map_err(|why| format!("scene: buffer {} {why}", buffer.index()))?;
        }
    }
    for image in gltf.document.images() {
        if let gltf::image::Source::Uri { uri, .. } = image.source() {
            let data = embedded(uri).map_err(|why| format!("scene: image {} {why}", image.index()))?;
            rtd_image::read_image_header(Path::new("scene image"), &data).map_err(|e| format!("{e}"))?;
        }
    }
    Ok(format)
}

/// The bytes of a `data:` URI, or why the URI is refused.
fn embedded(uri: &str) -> Result<Vec<u8>, String> {
    let Some(rest) = uri.strip_prefix("data:") else {
        let what = if uri.contains("..") {
            "climbs out of its folder"
        } else if uri.starts_with('/') || uri.contains(':') {
            "names an absolute path or another scheme"
        } else {
            "names a file"
        };
        return Err(format!("refers to {uri:?}, which {what}; upload a .glb or a .gltf with data: URIs"));
    };
    let (_, payload) = rest.split_once(";base64,").ok_or("has a data: URI that is not base64")?;
    base64::engine::general_purpose::STANDARD.decode(payload).map_err(|e| format!("has a bad base64 data: URI ({e})"))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn gltf_with_buffer(uri: &str) -> Vec<u8> {
        format!(r#"{{"asset":{{"version":"2.0"}},"buffers":[{{"byteLength":4,"uri":"{uri}"}}]}}"#).into_bytes()
    }

    #[test]
    fn files_outside_the_scene_are_refused() {
        for uri in ["../../etc/passwd", "/etc/passwd", "file:///etc/passwd", "mesh.bin"] {
            let err = check_scene(&gltf_with_buffer(uri)).unwrap_err();
            assert!(err.starts_with("scene: buffer 0 refers to"), "{err}");
        }
        assert_eq!(check_scene(&gltf_with_buffer("data:application/octet-stream;base64,AAAAAA==")), Ok("gltf"));
        assert!(check_scene(b"<html>").is_err());
    }

    #[test]
    fn unsupported_required_extensions_are_refused() {
        let doc = br#"{"asset":{"version":"2.0"},"extensionsUsed":["KHR_draco_mesh_compression"],"extensionsRequired":["KHR_draco_mesh_compression"]}"#;
        assert!(check_scene(doc).unwrap_err().contains("KHR_draco_mesh_compression"));
    }
}
