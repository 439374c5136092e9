//! `rtd guide`: the rasterised guide pass on its own.

use anyhow::bail;
use serde::Serialize;

use rtd_guide::{GuidePass, GuideSettings};
use rtd_image::{ImageFormat, Tonemap};

use crate::args::GuideArgs;
use crate::output::{check_output, check_report_path};
use rtd_image::write_json;

/// What `rtd guide --report` writes.
#[derive(Debug, Clone, Serialize)]
pub struct GuideReport {
    /// Scene file.
    pub scene: String,
    /// Output file.
    pub output: String,
    /// Image width.
    pub width: u32,
    /// Image height.
    pub height: u32,
    /// Scene loading seconds.
    pub load_s: f64,
    /// BVH build seconds.
    pub bvh_s: f64,
    /// The guide pass itself: rasterisation, shading and AO.
    pub guide_s: f64,
    /// Triangles in the scene.
    pub triangles: usize,
}

/// Runs `rtd guide` and returns its report.
pub fn guide(args: &GuideArgs) -> anyhow::Result<GuideReport> {
    let view = &args.view;
    check_output(&args.output)?;
    if let Some(r) = &args.report {
        check_report_path(r)?;
    }
    let (loaded, (width, height)) = view.load(None)?;
    let prepared = &loaded.scene;
    let settings = GuideSettings::new(width, height)
        .ao_rays(args.ao_rays)
        .ao_radius(args.ao_radius)
        .threads(view.threads.map(|t| t as usize));
    let pass = GuidePass::render(&prepared.scene, &prepared.bvh, &loaded.camera, &settings)?;
    match ImageFormat::from_path(&args.output)? {
        ImageFormat::Exr => rtd_image::write_exr(&args.output, &pass.layers())?,
        format @ (ImageFormat::Pfm | ImageFormat::Phm) => {
            rtd_image::write_pfm(&args.output, &pass.guide, format == ImageFormat::Phm)?
        }
        ImageFormat::Png | ImageFormat::Jpeg => rtd_image::write_ldr(&args.output, &pass.guide, 0.0, Tonemap::Clamp)?,
    }
    if !pass.guide.is_finite() {
        bail!("internal error: the guide pass produced non-finite values");
    }
    let report = GuideReport {
        scene: view.scene.display().to_string(),
        output: args.output.display().to_string(),
        width,
        height,
        load_s: loaded.load_s,
        bvh_s: prepared.bvh_seconds,
        guide_s: pass.seconds,
        triangles: prepared.scene.triangles.len(),
    };
    crate::print_line(&format!(
        "guide pass {}x{} in {:.3} s ({} triangles)",
        width, height, pass.seconds, report.triangles
    ))?;
    if let Some(path) = &args.report {
        write_json(path, &report)?;
    }
    Ok(report)
}
