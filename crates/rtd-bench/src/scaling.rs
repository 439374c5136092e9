//! `rtd bench scaling`: how each cost grows along each axis a user scales — triangles,
//! emitters, resolution, texture size and samples per pixel — on generated scenes
//! ([`crate::procedural`]). Every point is measured in a process of its own (so that its peak
//! memory is its own): load, BVH build, BVH bytes per triangle, peak RSS, paths/s and rays/s,
//! guide and denoise seconds, each the median of several runs with its range. The report fits
//! a power law to each curve (the exponent of cost against the axis) and plots them log-log.

use std::path::{Path, PathBuf};

use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rtd_denoise::Denoiser;
use rtd_image::{Progress, Quiet};
use rtd_pipeline::{Budget, CameraChoice, Pipeline, SceneView};
use rtd_plot::{write_charts, Chart, Series};
use rtd_render::RenderSettings;
use rtd_train::scenegen::{make_texture, GenMaterial, GenScene, Mesh, Pattern};
use serde::{Deserialize, Serialize};

use crate::procedural::{lit_room, room_with_lights, write_scene};
use crate::speed::Spread;
use crate::BenchError;

/// An axis a user scales.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Axis {
    /// Triangles in the scene (a displaced mesh in a lit room).
    Triangles,
    /// Emissive quads (two triangles each) lighting a room.
    Lights,
    /// Image pixels.
    Resolution,
    /// Side of a square base-colour texture, in texels.
    Texture,
    /// Samples per pixel.
    Spp,
}

/// Most triangles of a generated point: the 10M-triangle extreme peaks at 3.5 GiB, so twice
/// that stays well inside 24 GiB.
pub const MAX_POINT_TRIANGLES: u64 = 20_000_000;
/// Most emitters of a generated point (the sweep's largest is 10k).
pub const MAX_POINT_LIGHTS: u64 = 100_000;

impl Axis {
    /// Every axis, in report order.
    pub const ALL: [Axis; 5] = [Axis::Triangles, Axis::Lights, Axis::Resolution, Axis::Texture, Axis::Spp];

    /// The axis's name on the command line and in reports.
    pub fn name(self) -> &'static str {
        match self {
            Axis::Triangles => "triangles",
            Axis::Lights => "lights",
            Axis::Resolution => "resolution",
            Axis::Texture => "texture",
            Axis::Spp => "spp",
        }
    }

    /// The axis named `name`.
    pub fn parse(name: &str) -> Option<Axis> {
        Axis::ALL.into_iter().find(|a| a.name() == name)
    }

    /// The values measured: the full sweep, or a short one (`quick`).
    pub fn values(self, quick: bool) -> Vec<u64> {
        let all: &[u64] = match self {
            Axis::Triangles => &[1_000, 4_000, 16_000, 64_000, 256_000, 1_000_000, 4_000_000],
            Axis::Lights => &[1, 10, 100, 1_000, 10_000],
            Axis::Resolution => &[256 * 256, 512 * 512, 1024 * 1024, 1920 * 1080, 3840 * 2160],
            Axis::Texture => &[256, 1024, 4096, 8192],
            Axis::Spp => &[1, 4, 16, 64],
        };
        all.iter().copied().take(if quick { 2 } else { all.len() }).collect()
    }

    /// The values a single point (`rtd bench scaling --point AXIS=VALUE`) may take, so that a
    /// generated scene fits the 24 GiB machines rtd targets. A texture side up to
    /// [`rtd_image::MAX_DIMENSION`] is generated, so that the documented 16384² extreme can be
    /// run: the loader then refuses any over [`rtd_image::MAX_PIXELS`], with a one-line error.
    pub fn range(self) -> std::ops::RangeInclusive<u64> {
        match self {
            Axis::Triangles => 1..=MAX_POINT_TRIANGLES,
            Axis::Lights => 1..=MAX_POINT_LIGHTS,
            Axis::Resolution => 1..=rtd_image::MAX_PIXELS as u64,
            Axis::Texture => 1..=rtd_image::MAX_DIMENSION as u64,
            Axis::Spp => 1..=rtd_render::MAX_SPP as u64,
        }
    }

    /// Render width and height at `value` (the resolution axis's own sizes, else 256²).
    pub fn size(self, value: u64) -> (u32, u32) {
        match (self, value) {
            (Axis::Resolution, v) if v == 1920 * 1080 => (1920, 1080),
            (Axis::Resolution, v) if v == 3840 * 2160 => (3840, 2160),
            (Axis::Resolution, v) => ((v as f64).sqrt() as u32, (v as f64).sqrt() as u32),
            _ => (256, 256),
        }
    }

    /// Samples per pixel of each timed render at `value`.
    pub fn spp(self, value: u64) -> u32 {
        if self == Axis::Spp {
            value as u32
        } else {
            8
        }
    }

    /// The generated scene of this axis at `value`.
    pub fn scene(self, value: u64) -> GenScene {
        match self {
            Axis::Triangles => mesh_room(value),
            Axis::Lights => room_with_lights(&mut ChaCha8Rng::seed_from_u64(7), value as usize, false),
            Axis::Resolution | Axis::Spp => mesh_room(16_000),
            Axis::Texture => {
                let mut s = lit_room(2.0);
                s.textures.push(make_texture(Pattern::Noise, value as u32, &mut ChaCha8Rng::seed_from_u64(3)));
                s.materials.push(GenMaterial { texture: Some(0), ..GenMaterial::diffuse(glam::Vec3::ONE) });
                let (a, y) = (4.9, 0.01);
                let floor = Mesh::quad(
                    glam::Vec3::new(-a, y, a),
                    glam::Vec3::new(a, y, a),
                    glam::Vec3::new(a, y, -a),
                    glam::Vec3::new(-a, y, -a),
                    1.0,
                );
                s.objects.push((floor, s.materials.len() - 1));
                s
            }
        }
    }
}

/// A lit room holding a displaced sphere of about `triangles` triangles.
fn mesh_room(triangles: u64) -> GenScene {
    let mut s = lit_room(2.0);
    s.materials.push(GenMaterial { roughness: 0.4, ..GenMaterial::diffuse(glam::Vec3::new(0.6, 0.5, 0.4)) });
    // A UV sphere of n segments has 2n × n quads: about 4n² triangles.
    let n = ((triangles as f64 / 4.0).sqrt().round() as u32).max(3);
    let blob = Mesh::sphere(glam::Vec3::new(0.0, 1.2, 0.0), 1.1, n, &|d: glam::Vec3| {
        0.05 * (9.0 * d.x).sin() * (7.0 * d.y).cos() * (8.0 * d.z).sin()
    });
    s.objects.push((blob, s.materials.len() - 1));
    s
}

/// One point's measurements.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct ScalingPoint {
    /// The axis.
    pub axis: Axis,
    /// Its value.
    pub value: u64,
    /// Triangles in the loaded scene.
    pub triangles: usize,
    /// Image width and height.
    pub size: (u32, u32),
    /// Samples per pixel of each render.
    pub spp: u32,
    /// Seconds to load the scene file.
    pub load_s: f64,
    /// Seconds to build the BVH.
    pub bvh_s: f64,
    /// Bytes the BVH holds per triangle.
    pub bvh_bytes_per_triangle: f64,
    /// Bytes the loaded scene (triangles, side tables, textures) holds per triangle.
    pub scene_bytes_per_triangle: f64,
    /// Peak resident memory of the measuring process, MiB (None where the OS does not say).
    pub peak_rss_mib: Option<f64>,
    /// Render seconds (the whole `spp`).
    pub render_s: Spread,
    /// Millions of camera paths per second.
    pub mpaths_per_s: Spread,
    /// Millions of rays per second.
    pub mrays_per_s: Spread,
    /// Guide pass seconds.
    pub guide_s: Spread,
    /// Denoiser seconds.
    pub denoise_s: Spread,
}

/// Measures `axis` at `value`: writes its scene into `dir` (once), loads it, and runs the
/// pipeline `runs` times. Peak RSS is this process's, so callers measure one point a process.
pub fn measure_point(
    axis: Axis,
    value: u64,
    dir: &Path,
    denoiser: &Denoiser,
    runs: usize,
) -> Result<ScalingPoint, BenchError> {
    let name = format!("{}-{value}", axis.name());
    let path = write_scene(dir, &name, &axis.scene(value))?;
    let view = SceneView::load(&path, &CameraChoice::Default, None)?;
    let (w, h) = axis.size(value);
    let spp = axis.spp(value);
    let (mut render, mut paths, mut rays, mut guide, mut denoise) = (vec![], vec![], vec![], vec![], vec![]);
    for run in 0..runs.max(1) {
        let settings = RenderSettings::new(w, h).seed(run as u64);
        let r = Pipeline::new(&view, settings).denoise(denoiser).run(Budget::Samples(spp), &Quiet)?;
        render.push(r.stats.seconds);
        paths.push(r.stats.paths as f64 / r.stats.seconds / 1e6);
        rays.push(r.stats.rays as f64 / r.stats.seconds / 1e6);
        guide.push(r.timings.guide_s.unwrap_or(0.0));
        denoise.push(r.timings.denoise_s.unwrap_or(0.0));
    }
    let triangles = view.scene.scene.triangles.len();
    let per_tri = |bytes: usize| bytes as f64 / triangles.max(1) as f64;
    Ok(ScalingPoint {
        axis,
        value,
        triangles,
        size: (w, h),
        spp,
        load_s: view.load_s,
        bvh_s: view.scene.bvh_seconds,
        bvh_bytes_per_triangle: per_tri(view.scene.bvh.heap_bytes()),
        scene_bytes_per_triangle: per_tri(view.scene.scene.heap_bytes()),
        peak_rss_mib: peak_rss_mib(),
        render_s: Spread::of(render),
        mpaths_per_s: Spread::of(paths),
        mrays_per_s: Spread::of(rays),
        guide_s: Spread::of(guide),
        denoise_s: Spread::of(denoise),
    })
}

/// This process's peak resident set, from `/proc/self/status` (VmHWM), in MiB.
pub fn peak_rss_mib() -> Option<f64> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = status.lines().find(|l| l.starts_with("VmHWM:"))?;
    let kib: f64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kib / 1024.0)
}

/// A fitted power law y ≈ c · x^exponent over one curve.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct Fit {
    /// The axis.
    pub axis: Axis,
    /// The figure fitted (`load_s`, `render_us_per_path`, …).
    pub figure: String,
    /// The exponent: the least-squares slope of log y against log x.
    pub exponent: f64,
}

/// The whole report: every point and the fitted exponents.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct ScalingReport {
    /// Measured points, by axis and value.
    pub points: Vec<ScalingPoint>,
    /// Power-law exponents per axis and figure.
    pub fits: Vec<Fit>,
}

/// Each figure's legend label, with its unit.
fn figure_label(figure: &str) -> &'static str {
    match figure {
        "load_s" => "load (s)",
        "bvh_s" => "BVH build (s)",
        "render_us_per_path" => "render per path (µs)",
        "guide_s" => "guide pass (s)",
        "denoise_s" => "denoise (s)",
        _ => "peak RSS (MiB)",
    }
}

/// The figures plotted and fitted per point: (name, value).
fn figures(p: &ScalingPoint) -> Vec<(&'static str, f64)> {
    let paths = (p.size.0 as f64) * (p.size.1 as f64) * p.spp as f64;
    vec![
        ("load_s", p.load_s),
        ("bvh_s", p.bvh_s),
        ("render_us_per_path", p.render_s.median / paths * 1e6),
        ("guide_s", p.guide_s.median),
        ("denoise_s", p.denoise_s.median),
        ("peak_rss_mib", p.peak_rss_mib.unwrap_or(f64::NAN)),
    ]
}

/// The least-squares slope of log y against log x (None with fewer than two usable points).
pub fn power_law_exponent(points: &[(f64, f64)]) -> Option<f64> {
    let logs: Vec<(f64, f64)> =
        points.iter().filter(|(x, y)| *x > 0.0 && *y > 0.0 && y.is_finite()).map(|(x, y)| (x.ln(), y.ln())).collect();
    if logs.len() < 2 {
        return None;
    }
    let n = logs.len() as f64;
    let (mx, my) = (logs.iter().map(|p| p.0).sum::<f64>() / n, logs.iter().map(|p| p.1).sum::<f64>() / n);
    let sxx: f64 = logs.iter().map(|p| (p.0 - mx).powi(2)).sum();
    let sxy: f64 = logs.iter().map(|p| (p.0 - mx) * (p.1 - my)).sum();
    (sxx > 0.0).then(|| sxy / sxx)
}

impl ScalingReport {
    /// The report of `points`, with every curve's exponent fitted.
    pub fn new(points: Vec<ScalingPoint>) -> Self {
        let mut fits = vec![];
        for axis in Axis::ALL {
            let on: Vec<&ScalingPoint> = points.iter().filter(|p| p.axis == axis).collect();
            let Some(first) = on.first() else { continue };
            for (k, (figure, _)) in figures(first).iter().enumerate() {
                let curve: Vec<(f64, f64)> = on.iter().map(|p| (p.value as f64, figures(p)[k].1)).collect();
                if let Some(exponent) = power_law_exponent(&curve) {
                    fits.push(Fit { axis, figure: figure.to_string(), exponent });
                }
            }
        }
        ScalingReport { points, fits }
    }

    /// The fitted exponent of `figure` along `axis`.
    pub fn exponent(&self, axis: Axis, figure: &str) -> Option<f64> {
        self.fits.iter().find(|f| f.axis == axis && f.figure == figure).map(|f| f.exponent)
    }

    /// One table per axis: every figure at every value.
    pub fn markdown(&self) -> String {
        let mut md = String::from("# rtd bench scaling\n");
        for axis in Axis::ALL {
            let on: Vec<&ScalingPoint> = self.points.iter().filter(|p| p.axis == axis).collect();
            if on.is_empty() {
                continue;
            }
            md += &format!(
                "\n## {}\n\n| value | triangles | size | load s | BVH s | BVH B/tri | scene B/tri | peak RSS MiB | M paths/s (min–max) | M rays/s | guide s | denoise s |\n|---|---|---|---|---|---|---|---|---|---|---|---|\n",
                axis.name()
            );
            for p in on {
                md += &format!(
                    "| {} | {} | {}x{} | {:.3} | {:.3} | {:.0} | {:.0} | {} | {:.3} ({:.3}–{:.3}) | {:.3} | {:.4} | {:.4} |\n",
                    p.value,
                    p.triangles,
                    p.size.0,
                    p.size.1,
                    p.load_s,
                    p.bvh_s,
                    p.bvh_bytes_per_triangle,
                    p.scene_bytes_per_triangle,
                    p.peak_rss_mib.map_or("–".into(), |m| format!("{m:.0}")),
                    p.mpaths_per_s.median,
                    p.mpaths_per_s.min,
                    p.mpaths_per_s.max,
                    p.mrays_per_s.median,
                    p.guide_s.median,
                    p.denoise_s.median
                );
            }
            let fits: Vec<String> = self
                .fits
                .iter()
                .filter(|f| f.axis == axis)
                .map(|f| format!("{} ∝ x^{:.2}", f.figure, f.exponent))
                .collect();
            md += &format!("\nFitted: {}.\n", fits.join(", "));
        }
        md
    }

    /// One log-log chart per axis of the time figures (and peak memory), each legend entry
    /// with its fitted exponent.
    pub fn write_plot(&self, path: &Path) -> Result<(), BenchError> {
        let mut charts = vec![];
        for axis in Axis::ALL {
            let on: Vec<&ScalingPoint> = self.points.iter().filter(|p| p.axis == axis).collect();
            let Some(first) = on.first() else { continue };
            let x_label = match axis {
                Axis::Triangles => "triangles",
                Axis::Lights => "emissive quads",
                Axis::Resolution => "pixels",
                Axis::Texture => "texture side (texels)",
                Axis::Spp => "samples per pixel",
            };
            let mut chart = Chart::new(format!("cost against {}", axis.name()), x_label, "cost (unit in the legend)")
                .log(true, true);
            for (k, (figure, _)) in figures(first).iter().enumerate() {
                let exponent = self.exponent(axis, figure).map_or(String::new(), |e| format!(" ∝ x^{e:.2}"));
                let points = on.iter().map(|p| (p.value as f64, figures(p)[k].1)).collect();
                chart.series.push(Series::line(format!("{}{exponent}", figure_label(figure)), points));
            }
            charts.push(chart);
        }
        write_charts(path, &charts)?;
        Ok(())
    }
}

/// Measures every value of `axes`, each in a child process `exe bench scaling --point
/// AXIS=VALUE` whose JSON it reads (so each point's peak memory is its own), writing
/// `scaling.json`, `scaling.md` and `scaling.png` into `out` after every point.
pub fn run_scaling(
    exe: &Path,
    axes: &[Axis],
    quick: bool,
    runs: usize,
    model: Option<&Path>,
    out: &Path,
    progress: &dyn Progress,
) -> Result<ScalingReport, BenchError> {
    let scenes = out.join("scenes");
    std::fs::create_dir_all(&scenes).map_err(|e| BenchError::io(&scenes, e))?;
    let todo: Vec<(Axis, u64)> = axes.iter().flat_map(|a| a.values(quick).into_iter().map(move |v| (*a, v))).collect();
    progress.start(todo.len() as u64, "scaling");
    let mut points = vec![];
    for (axis, value) in todo {
        if progress.cancelled() {
            break;
        }
        let mut cmd = std::process::Command::new(exe);
        cmd.args(["bench", "scaling", "--point", &format!("{}={value}", axis.name()), "--runs", &runs.to_string()]);
        cmd.arg("-o").arg(&scenes);
        if let Some(m) = model {
            cmd.arg("--model").arg(m);
        }
        let child = cmd.output().map_err(|e| BenchError::io(exe, e))?;
        if !child.status.success() {
            let why = String::from_utf8_lossy(&child.stderr).trim().to_string();
            return Err(BenchError::msg(exe, format!("measuring {}={value} failed: {why}", axis.name())));
        }
        let point: ScalingPoint = serde_json::from_slice(&child.stdout)
            .map_err(|e| BenchError::msg(exe, format!("measuring {}={value}: unreadable output: {e}", axis.name())))?;
        points.push(point);
        let report = ScalingReport::new(points.clone());
        write_report(&report, out)?;
        progress.inc(1);
    }
    Ok(ScalingReport::new(points))
}

/// Writes `scaling.json`, `scaling.md` and `scaling.png`.
pub fn write_report(report: &ScalingReport, out: &Path) -> Result<Vec<PathBuf>, BenchError> {
    let (json, md, png) = (out.join("scaling.json"), out.join("scaling.md"), out.join("scaling.png"));
    rtd_image::write_json(&json, report)?;
    crate::report_files::write_text(&md, &report.markdown())?;
    report.write_plot(&png)?;
    Ok(vec![json, md, png])
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn exponents_of_known_power_laws() {
        let curve = |k: f64| (1..6).map(|i| (10f64.powi(i), 3.0 * 10f64.powi(i).powf(k))).collect::<Vec<_>>();
        for k in [0.0, 0.5, 1.0, 2.0] {
            assert!((power_law_exponent(&curve(k)).unwrap() - k).abs() < 1e-9, "{k}");
        }
        assert_eq!(power_law_exponent(&[(1.0, 1.0)]), None);
        assert_eq!(power_law_exponent(&[(1.0, 1.0), (1.0, 2.0)]), None, "one x value fits nothing");
    }

    #[test]
    fn axis_scenes_grow_along_their_axis() {
        let tris = |v: u64| {
            let s = Axis::Triangles.scene(v);
            s.objects.iter().map(|(m, _)| m.indices.len() / 3).sum::<usize>()
        };
        let (small, large) = (tris(16_000), tris(64_000));
        assert!((14_000..18_000).contains(&small) && (58_000..70_000).contains(&large), "{small} {large}");
        let lights = Axis::Lights.scene(100);
        assert_eq!(lights.materials.iter().filter(|m| m.emissive != glam::Vec3::ZERO).count(), 100);
        assert_eq!(Axis::Resolution.size(1920 * 1080), (1920, 1080));
        assert_eq!(Axis::Texture.scene(256).textures[0].dimensions(), (256, 256));
        assert_eq!(Axis::parse("spp"), Some(Axis::Spp));
    }
}
