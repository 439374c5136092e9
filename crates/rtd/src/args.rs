//! Command-line arguments (clap derive).

use std::path::PathBuf;

use clap::{Args, Parser, Subcommand, ValueEnum};

/// rtd: a Monte Carlo path tracer with a built-in learned denoiser.
#[derive(Debug, Parser)]
#[command(name = "rtd", version, about)]
pub struct Cli {
    /// What to do.
    #[command(subcommand)]
    pub command: Command,
}

/// The subcommands.
#[derive(Debug, Subcommand)]
pub enum Command {
    /// Path-trace a glTF/GLB/OBJ scene to EXR, PNG or JPEG.
    Render(RenderArgs),
    /// Rasterise the guide pass (albedo, normal, depth, AO and albedo × AO) of a scene.
    Guide(GuideArgs),
}

/// Tonemap choice for 8-bit outputs.
#[derive(Debug, Clone, Copy, ValueEnum, PartialEq, Eq)]
pub enum TonemapArg {
    /// Clamp to [0,1].
    Clamp,
    /// ACES filmic curve.
    Aces,
}

/// The scene, resolution and camera: shared by every command that renders a view.
#[derive(Debug, Clone, Args)]
pub struct ViewArgs {
    /// Scene file (.gltf, .glb or .obj).
    pub scene: PathBuf,
    /// Image width in pixels.
    #[arg(long, default_value_t = 512, value_parser = clap::value_parser!(u32).range(1..=rtd_render::MAX_RESOLUTION as i64))]
    pub width: u32,
    /// Image height in pixels.
    #[arg(long, default_value_t = 512, value_parser = clap::value_parser!(u32).range(1..=rtd_render::MAX_RESOLUTION as i64))]
    pub height: u32,
    /// Camera by name or index (default: the first perspective camera in the file).
    #[arg(long)]
    pub camera: Option<String>,
    /// Camera position for files without cameras (OBJ), as x,y,z.
    #[arg(long, value_parser = parse_vec3, requires = "look_at")]
    pub look_from: Option<glam::Vec3>,
    /// Camera target, as x,y,z.
    #[arg(long, value_parser = parse_vec3, requires = "look_from")]
    pub look_at: Option<glam::Vec3>,
    /// Vertical field of view in degrees for --look-from/--look-at.
    #[arg(long, default_value_t = 45.0, value_parser = parse_fov)]
    pub fov: f32,
    /// Worker threads (default: all cores).
    #[arg(long, value_parser = clap::value_parser!(u32).range(1..=1024))]
    pub threads: Option<u32>,
    /// Hide the progress bar.
    #[arg(long, short)]
    pub quiet: bool,
}

/// Arguments of `rtd render`.
#[derive(Debug, Clone, Args)]
pub struct RenderArgs {
    /// Scene, resolution and camera.
    #[command(flatten)]
    pub view: ViewArgs,
    /// Output image; the format follows the extension (.exr, .png, .jpg).
    #[arg(short, long)]
    pub output: PathBuf,
    /// Samples per pixel (default 16).
    #[arg(long, value_parser = clap::value_parser!(u32).range(1..=rtd_render::MAX_SPP as i64), conflicts_with = "time")]
    pub spp: Option<u32>,
    /// Render whole 1-spp passes until this many seconds are spent.
    #[arg(long, value_parser = parse_seconds, allow_hyphen_values = true)]
    pub time: Option<f64>,
    /// Random seed.
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// Maximum path depth (bounces).
    #[arg(long, default_value_t = 12, value_parser = clap::value_parser!(u32).range(1..=1024))]
    pub max_depth: u32,
    /// Environment: R,G,B radiance or an equirectangular .exr map.
    #[arg(long)]
    pub env: Option<String>,
    /// Clamp each sample's largest channel to this value (biased; off by default).
    #[arg(long, value_parser = parse_positive, allow_hyphen_values = true)]
    pub clamp: Option<f32>,
    /// Exposure in stops for 8-bit outputs.
    #[arg(long, default_value_t = 0.0, allow_hyphen_values = true)]
    pub exposure: f32,
    /// Tonemap for 8-bit outputs.
    #[arg(long, value_enum, default_value_t = TonemapArg::Clamp)]
    pub tonemap: TonemapArg,
    /// Also run the guide pass and write its layers (guide, albedo, normal, depth, ao) to the EXR.
    #[arg(long)]
    pub aov: bool,
    /// Write a JSON report of timings and counters here.
    #[arg(long)]
    pub report: Option<PathBuf>,
}

/// Arguments of `rtd guide`.
#[derive(Debug, Clone, Args)]
pub struct GuideArgs {
    /// Scene, resolution and camera.
    #[command(flatten)]
    pub view: ViewArgs,
    /// Output: .exr (all guide layers) or .png/.jpg (the guide RGB as sRGB).
    #[arg(short, long)]
    pub output: PathBuf,
    /// Occlusion rays per AO evaluation.
    #[arg(long, default_value_t = 24, value_parser = clap::value_parser!(u32).range(1..=4096))]
    pub ao_rays: u32,
    /// AO radius in scene units (default: 10% of the scene's bounding-box diagonal).
    #[arg(long, value_parser = parse_positive, allow_hyphen_values = true)]
    pub ao_radius: Option<f32>,
    /// Write a JSON report (with guide_s) here.
    #[arg(long)]
    pub report: Option<PathBuf>,
}

fn parse_vec3(s: &str) -> Result<glam::Vec3, String> {
    let v: Vec<f32> = s
        .split(',')
        .map(|x| x.trim().parse::<f32>().map_err(|_| format!("'{s}' is not x,y,z")))
        .collect::<Result<_, _>>()?;
    match v.as_slice() {
        [x, y, z] if v.iter().all(|c| c.is_finite()) => Ok(glam::Vec3::new(*x, *y, *z)),
        _ => Err(format!("'{s}' is not three finite numbers x,y,z")),
    }
}

fn parse_seconds(s: &str) -> Result<f64, String> {
    match s.parse::<f64>() {
        Ok(t) if t > 0.0 && t.is_finite() && t <= 7.0 * 86400.0 => Ok(t),
        _ => Err(format!("'{s}' is not a number of seconds in (0, 604800]")),
    }
}

fn parse_positive(s: &str) -> Result<f32, String> {
    match s.parse::<f32>() {
        Ok(v) if v > 0.0 && v.is_finite() => Ok(v),
        _ => Err(format!("'{s}' is not a positive finite number")),
    }
}

fn parse_fov(s: &str) -> Result<f32, String> {
    match s.parse::<f32>() {
        Ok(v) if v > 0.0 && v < 180.0 => Ok(v),
        _ => Err(format!("'{s}' is not a field of view in (0, 180) degrees")),
    }
}
