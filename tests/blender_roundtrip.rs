//! A room built in Blender 5.0 and exported by Blender's own glTF exporter at its defaults
//! (`tests/blender/all.glb`: rough dielectrics, a rough metal and a glass sphere, point, spot,
//! sun and emissive lighting, a 16:9 camera) renders as Cycles renders the `.blend`: the image
//! mean within 3% and the 8×8 block means within 5% relative on average. Cycles' numbers (1024
//! spp, 160×90) are stored beside it by `benches/blender_roundtrip.py --store-reference`, so
//! this test needs no Blender.

mod common;

use common::cli::rtd;

#[test]
fn a_blender_export_renders_as_cycles_renders_it() {
    let dir = common::repo_path("tests/blender");
    let reference: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("all-cycles.json")).unwrap()).unwrap();
    let (w, h) = (reference["size"][0].as_u64().unwrap() as u32, reference["size"][1].as_u64().unwrap() as u32);
    let work = tempfile::tempdir().unwrap();
    let out = work.path().join("room.pfm");
    let (ws, hs) = (w.to_string(), h.to_string());
    let scene = dir.join("all.glb");
    let o = rtd(&[
        "render",
        scene.to_str().unwrap(),
        "-o",
        out.to_str().unwrap(),
        "--spp",
        "256",
        "--width",
        &ws,
        "--height",
        &hs,
        "-q",
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    // No size warning: the camera's 16:9 aspect ratio is what was asked for.
    assert!(String::from_utf8_lossy(&o.stderr).trim().is_empty(), "{}", String::from_utf8_lossy(&o.stderr));
    let img = rtd::image::read_pfm(&out).unwrap();
    let grey: Vec<f64> = img.pixels.iter().map(|p| ((p.x + p.y + p.z) / 3.0) as f64).collect();
    let mean = grey.iter().sum::<f64>() / grey.len() as f64;
    let want_rgb: Vec<f64> = reference["mean_rgb"].as_array().unwrap().iter().map(|v| v.as_f64().unwrap()).collect();
    let want = want_rgb.iter().sum::<f64>() / 3.0;
    eprintln!("mean rtd {mean:.4}, Cycles {want:.4} (ratio {:.4})", mean / want);
    assert!((mean / want - 1.0).abs() < 0.03, "image mean {mean} against Cycles' {want}");
    let blocks = reference["blocks"].as_array().unwrap();
    let (mut sum, mut n) = (0.0, 0);
    for (by, row) in blocks.iter().enumerate() {
        for (bx, cycles) in row.as_array().unwrap().iter().enumerate() {
            let cycles = cycles.as_f64().unwrap();
            if cycles <= 0.01 * want {
                continue;
            }
            let mut ours = 0.0;
            for y in by * 8..by * 8 + 8 {
                for x in bx * 8..bx * 8 + 8 {
                    ours += grey[y * w as usize + x];
                }
            }
            sum += (ours / 64.0 - cycles).abs() / cycles;
            n += 1;
        }
    }
    let block_error = sum / n as f64;
    eprintln!("8x8 blocks: mean relative difference {:.2}% over {n}", 100.0 * block_error);
    assert!(n > 100 && block_error < 0.05, "8x8 block means differ from Cycles' by {block_error} on average");
}
