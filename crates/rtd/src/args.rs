//! Command-line arguments (clap derive).

use std::path::PathBuf;

use clap::{Args, Parser, Subcommand, ValueEnum};

/// The denoiser a command runs: `--model` and `--ensemble`.
#[derive(Debug, Clone, Args)]
pub struct DenoiserArgs {
    /// Denoiser model (.bpk with its .json beside it) instead of the built-in one.
    #[arg(long)]
    pub model: Option<PathBuf>,
    /// Self-ensemble: average the denoiser's outputs over this many flips/transposes of
    /// the input (1 to 8; each costs a whole run).
    #[arg(long, default_value_t = 1, value_parser = clap::value_parser!(u32).range(1..=rtd_denoise::infer::MAX_PASSES as i64))]
    pub ensemble: u32,
}

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
    /// Generate procedural scenes and render the denoiser's training set (resumable).
    Datagen(crate::train_args::DatagenArgs),
    /// Denoise a noisy render (from rtd or other software) with its guide image.
    Denoise(DenoiseArgs),
    /// Benchmarks: validation-set comparison, equal-time (ETRT) reports, speed.
    Bench(BenchArgs),
    /// Train the denoiser on a `rtd datagen` dataset (resumable; --quick for a smoke run).
    Train(crate::train_args::TrainArgs),
    /// The web service: upload page, JSON API and job queue (SQLite, or PostgreSQL for many machines).
    Serve(crate::service_args::ServeArgs),
    /// A render node: takes jobs from the service's database until stopped.
    Worker(crate::service_args::WorkerArgs),
}

/// `rtd denoise` options.
#[derive(Debug, Clone, Args)]
pub struct DenoiseArgs {
    /// Noisy colour: .exr (any renderer's beauty pass), .pfm/.phm, or .png/.jpg (taken as sRGB).
    #[arg(long, visible_alias = "hdr")]
    pub color: PathBuf,
    /// Guide image: material colour × AO (EXR `guide.*` or `R,G,B`, PFM, or sRGB PNG/JPEG).
    #[arg(long)]
    pub guide: Option<PathBuf>,
    /// Albedo image (EXR `albedo.*`, Blender's `Denoising Albedo`, or `R,G,B`; PFM; or sRGB
    /// PNG/JPEG). Without --guide it stands in for the guide; alone with --color it is OIDN's
    /// colour + albedo mode.
    #[arg(long, visible_alias = "alb")]
    pub albedo: Option<PathBuf>,
    /// Normals, world or camera space (EXR `normal.X/Y/Z`, Blender's `Denoising Normal`, or
    /// `R,G,B`; PFM; PNG/JPEG as n·0.5+0.5). Needs --albedo.
    #[arg(long, visible_alias = "nrm", requires = "albedo")]
    pub normal: Option<PathBuf>,
    /// EXR layer to read the colour from (its name, or the last part of a name such as
    /// `ViewLayer.Combined`), when rtd's search by pass name does not find it.
    #[arg(long, value_name = "NAME")]
    pub layer_color: Option<String>,
    /// EXR layer to read the albedo from.
    #[arg(long, value_name = "NAME")]
    pub layer_albedo: Option<String>,
    /// EXR layer to read the normal from.
    #[arg(long, value_name = "NAME")]
    pub layer_normal: Option<String>,
    /// The denoiser: model and self-ensemble passes.
    #[command(flatten)]
    pub denoiser: DenoiserArgs,
    /// Output: .exr (the colour file's channels with the denoised colour in place of the noisy,
    /// or the denoised R,G,B with the inputs as noisy.*, guide.*, albedo.*, normal.* layers),
    /// .pfm/.phm, or .png/.jpg.
    #[arg(short, long)]
    pub output: PathBuf,
    /// Exposure in stops for 8-bit outputs.
    #[arg(long, default_value_t = 0.0, allow_hyphen_values = true)]
    pub exposure: f32,
    /// Write a JSON report (denoise_s, model, sizes) here.
    #[arg(long)]
    pub report: Option<PathBuf>,
}

/// `rtd bench` options.
#[derive(Debug, Clone, Args)]
pub struct BenchArgs {
    /// Which benchmark.
    #[command(subcommand)]
    pub which: BenchCommand,
}

/// The benchmarks.
#[derive(Debug, Clone, Subcommand)]
pub enum BenchCommand {
    /// Compare noisy, rtd (all guides / guide RGB only / albedo + normal as OIDN is given), the
    /// noisy-as-guide ablation, the guided-filter baseline and external results on a dataset's
    /// validation views.
    Validation(ValidationArgs),
    /// Equal-time comparison on one scene: rtd (low spp + guide + denoise) against plain path
    /// tracing given the same wall time, scored against a reference.
    Etrt(EtrtArgs),
    /// ETRT plus an spp sweep (1–64) over several scenes (default: the bundled ones), with a
    /// summary table and plots.
    Suite(SuiteArgs),
    /// Render paths/s and rays/s, guide and denoise seconds per megapixel (medians of runs).
    Speed(SpeedArgs),
    /// How load, BVH, memory, render, guide and denoise costs grow with triangles, lights,
    /// resolution, texture size and spp, on generated scenes, each point in its own process.
    Scaling(ScalingArgs),
    /// The light tree against power-proportional light selection at equal time, scored
    /// against one reference (default: the generated 10 m room and 80 m hall of 1,024 small
    /// lights each).
    Lights(LightsArgs),
    /// Write the broader benchmark scene set (strands, fine textures, many small lights, an
    /// instanced mesh, a glossy interior, flat walls) as glTF, for `rtd bench suite DIR` and
    /// the other benchmarks.
    Scenes(ScenesArgs),
}

/// `rtd bench scaling` options.
#[derive(Debug, Clone, Args)]
pub struct ScalingArgs {
    /// Axes to measure (comma-separated: triangles, lights, resolution, texture, spp).
    #[arg(long, value_delimiter = ',', default_value = "triangles,lights,resolution,texture,spp", value_parser = parse_axis)]
    pub axes: Vec<rtd_bench::scaling::Axis>,
    /// The first two values of each axis only.
    #[arg(long)]
    pub quick: bool,
    /// Runs per figure.
    #[arg(long, default_value_t = 3, value_parser = clap::value_parser!(u32).range(1..=100))]
    pub runs: u32,
    /// Denoiser model (.bpk with its .json beside it) instead of the built-in one.
    #[arg(long)]
    pub model: Option<PathBuf>,
    /// Output directory (scaling.json, scaling.md, scaling.png, and the generated scenes).
    #[arg(short, long)]
    pub output: PathBuf,
    /// Measure one point (AXIS=VALUE) in this process and print it as JSON: what each point's
    /// own process runs.
    #[arg(long, hide = true)]
    pub point: Option<String>,
    /// Hide the progress bar.
    #[arg(long, short)]
    pub quiet: bool,
}

fn parse_axis(s: &str) -> Result<rtd_bench::scaling::Axis, String> {
    rtd_bench::scaling::Axis::parse(s)
        .ok_or_else(|| format!("unknown axis {s:?} (triangles, lights, resolution, texture, spp)"))
}

/// `rtd bench lights` options.
#[derive(Debug, Clone, Args)]
pub struct LightsArgs {
    /// Scene file (default: the broader set's many-small-lights room and light hall, written
    /// into the output directory).
    pub scene: Option<PathBuf>,
    /// Seconds each strategy renders for.
    #[arg(long, default_value_t = 10.0, value_parser = parse_seconds)]
    pub seconds: f64,
    /// Reference samples per pixel.
    #[arg(long, default_value_t = 4096, value_parser = clap::value_parser!(u32).range(1..=1 << 20))]
    pub reference_spp: u32,
    /// Image width.
    #[arg(long, default_value_t = 256, value_parser = clap::value_parser!(u32).range(16..=rtd_image::MAX_DIMENSION as i64))]
    pub width: u32,
    /// Image height.
    #[arg(long, default_value_t = 256, value_parser = clap::value_parser!(u32).range(16..=rtd_image::MAX_DIMENSION as i64))]
    pub height: u32,
    /// Output directory (report.json, report.md).
    #[arg(short, long)]
    pub output: PathBuf,
}

/// `rtd bench scenes` options.
#[derive(Debug, Clone, Args)]
pub struct ScenesArgs {
    /// Output directory.
    #[arg(short, long)]
    pub output: PathBuf,
}

/// `rtd bench speed` options.
#[derive(Debug, Clone, Args)]
pub struct SpeedArgs {
    /// Scene file (default: the bundled Cornell box).
    #[arg(default_value = "scenes/cornell-box.gltf")]
    pub scene: PathBuf,
    /// Image width.
    #[arg(long, default_value_t = 512, value_parser = clap::value_parser!(u32).range(16..=rtd_image::MAX_DIMENSION as i64))]
    pub width: u32,
    /// Image height.
    #[arg(long, default_value_t = 512, value_parser = clap::value_parser!(u32).range(16..=rtd_image::MAX_DIMENSION as i64))]
    pub height: u32,
    /// Samples per pixel of each timed render.
    #[arg(long, default_value_t = 8, value_parser = clap::value_parser!(u32).range(1..=65536))]
    pub spp: u32,
    /// Runs per figure.
    #[arg(long, default_value_t = 5, value_parser = clap::value_parser!(u32).range(1..=1000))]
    pub runs: u32,
    /// The denoiser: model and self-ensemble passes.
    #[command(flatten)]
    pub denoiser: DenoiserArgs,
    /// Write the report as JSON here.
    #[arg(long)]
    pub report: Option<PathBuf>,
    /// Hide the progress bar.
    #[arg(long, short)]
    pub quiet: bool,
}

/// `rtd bench suite` options.
#[derive(Debug, Clone, Args)]
pub struct SuiteArgs {
    /// Scene files or directories of them (default: the bundled scenes/).
    pub scenes: Vec<PathBuf>,
    /// Pipeline, reference and image size.
    #[command(flatten)]
    pub pipeline: PipelineArgs,
    /// Output directory.
    #[arg(short, long)]
    pub output: PathBuf,
    /// Hide the progress bar.
    #[arg(long, short)]
    pub quiet: bool,
}

/// What `rtd bench etrt` and `rtd bench suite` measure: the pipeline's sample count, the
/// reference's, the image size and the model.
#[derive(Debug, Clone, Args)]
pub struct PipelineArgs {
    /// Samples per pixel of the denoised pipeline.
    #[arg(long, default_value_t = 8, value_parser = clap::value_parser!(u32).range(1..=65536))]
    pub spp: u32,
    /// Samples per pixel of a rendered reference's first round; it doubles while its estimated
    /// remaining relMSE is above --reference-relmse, up to --reference-max-spp.
    #[arg(long, default_value_t = 1024, value_parser = clap::value_parser!(u32).range(2..=1_048_576))]
    pub reference_spp: u32,
    /// The estimated remaining relMSE (from two independent halves) a rendered reference is
    /// doubled down to.
    #[arg(long, default_value_t = 1e-3, value_parser = parse_relmse)]
    pub reference_relmse: f64,
    /// The most samples per pixel a rendered reference may take.
    #[arg(long, default_value_t = 16384, value_parser = clap::value_parser!(u32).range(2..=1_048_576))]
    pub reference_max_spp: u32,
    /// Image width.
    #[arg(long, default_value_t = 256, value_parser = clap::value_parser!(u32).range(16..=rtd_image::MAX_DIMENSION as i64))]
    pub width: u32,
    /// Image height.
    #[arg(long, default_value_t = 256, value_parser = clap::value_parser!(u32).range(16..=rtd_image::MAX_DIMENSION as i64))]
    pub height: u32,
    /// The denoiser: model and self-ensemble passes.
    #[command(flatten)]
    pub denoiser: DenoiserArgs,
}

/// `rtd bench etrt` options.
#[derive(Debug, Clone, Args)]
pub struct EtrtArgs {
    /// Scene file (its first camera is used).
    pub scene: PathBuf,
    /// Pipeline, reference and image size.
    #[command(flatten)]
    pub pipeline: PipelineArgs,
    /// A reference EXR to score against (default: render one, cached).
    #[arg(long, conflicts_with_all = ["reference_spp", "reference_relmse", "reference_max_spp"])]
    pub reference: Option<PathBuf>,
    /// Seed of the measured render.
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// Output directory: report.json, report.md, side-by-side.png, error-vs-time.png.
    #[arg(short, long)]
    pub output: PathBuf,
    /// Hide the progress bar.
    #[arg(long, short)]
    pub quiet: bool,
}

/// `rtd bench validation` options.
#[derive(Debug, Clone, Args)]
pub struct ValidationArgs {
    /// Dataset directory made by `rtd datagen`.
    #[arg(long)]
    pub data: PathBuf,
    /// The denoiser: model and self-ensemble passes.
    #[command(flatten)]
    pub denoiser: DenoiserArgs,
    /// Noisy sample count to evaluate (one of the dataset's levels).
    #[arg(long, default_value_t = 8)]
    pub spp: u32,
    /// Another denoiser's outputs, as NAME=DIR with DIR/<view>.exr per validation view.
    #[arg(long = "external", value_parser = parse_named_dir)]
    pub external: Vec<(String, PathBuf)>,
    /// Also write rtd's all-guides output of each validation view here, as DIR/<view>.exr
    /// (the layout `--external` reads).
    #[arg(long)]
    pub save_images: Option<PathBuf>,
    /// Output directory for report.json and report.md.
    #[arg(short, long)]
    pub output: PathBuf,
    /// Hide the progress bar.
    #[arg(long, short)]
    pub quiet: bool,
}

fn parse_named_dir(s: &str) -> Result<(String, PathBuf), String> {
    let (name, dir) = s.split_once('=').ok_or("expected NAME=DIR")?;
    Ok((name.to_string(), PathBuf::from(dir)))
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
    /// Image width in pixels (default: 512, or from --height and the camera's aspect ratio).
    #[arg(long, value_parser = clap::value_parser!(u32).range(1..=rtd_image::MAX_DIMENSION as i64))]
    pub width: Option<u32>,
    /// Image height in pixels (default: from the width and the camera's aspect ratio; square
    /// when the file gives none).
    #[arg(long, value_parser = clap::value_parser!(u32).range(1..=rtd_image::MAX_DIMENSION as i64))]
    pub height: Option<u32>,
    /// glTF scene by name or index (default: the file's default scene).
    #[arg(long = "scene", value_name = "NAME|INDEX")]
    pub scene_choice: Option<String>,
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
    #[arg(long, default_value_t = 12, value_parser = clap::value_parser!(u32).range(1..=rtd_render::MAX_DEPTH as i64))]
    pub max_depth: u32,
    /// Environment: R,G,B radiance or an equirectangular map (.exr, .hdr, .pfm or .phm).
    #[arg(long)]
    pub env: Option<String>,
    /// Multiplies the environment's radiance (Blender's Background strength).
    #[arg(long, default_value_t = 1.0, requires = "env", allow_hyphen_values = true, value_parser = parse_non_negative)]
    pub env_strength: f32,
    /// Turns the environment map about the up axis by this many degrees, counter-clockwise seen
    /// from above (Blender's Z rotation in the world's Mapping node).
    #[arg(long, default_value_t = 0.0, requires = "env", allow_hyphen_values = true, value_parser = parse_finite)]
    pub env_rotation: f32,
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
    /// Denoise with the learned denoiser (implies the guide pass). EXR: R,G,B = denoised,
    /// noisy.R/G/B = the raw render; PNG/JPEG: the denoised image.
    #[arg(long)]
    pub denoise: bool,
    /// Denoiser model (.bpk with its .json beside it) instead of the built-in one.
    #[arg(long, requires = "denoise")]
    pub model: Option<PathBuf>,
    /// Self-ensemble: average the denoiser's outputs over this many flips/transposes of
    /// the input (1 to 8; each costs a whole run).
    #[arg(long, default_value_t = 1, value_parser = clap::value_parser!(u32).range(1..=rtd_denoise::infer::MAX_PASSES as i64), requires = "denoise")]
    pub ensemble: u32,
    /// Write a JSON report of timings and counters here.
    #[arg(long)]
    pub report: Option<PathBuf>,
}

impl RenderArgs {
    /// The `--model` and `--ensemble` of `--denoise`, as the other commands take them.
    pub fn denoiser(&self) -> DenoiserArgs {
        DenoiserArgs { model: self.model.clone(), ensemble: self.ensemble }
    }
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
    #[arg(long, default_value_t = rtd_guide::DEFAULT_AO_RAYS, value_parser = clap::value_parser!(u32).range(1..=rtd_guide::MAX_AO_RAYS as i64))]
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

fn parse_relmse(s: &str) -> Result<f64, String> {
    match s.parse::<f64>() {
        Ok(v) if v > 0.0 && v.is_finite() => Ok(v),
        _ => Err(format!("'{s}' is not a relMSE: it must be a positive finite number")),
    }
}

fn parse_positive(s: &str) -> Result<f32, String> {
    match s.parse::<f32>() {
        Ok(v) if v > 0.0 && v.is_finite() => Ok(v),
        _ => Err(format!("'{s}' is not a positive finite number")),
    }
}

fn parse_non_negative(s: &str) -> Result<f32, String> {
    match s.parse::<f32>() {
        Ok(v) if v >= 0.0 && v.is_finite() => Ok(v),
        _ => Err(format!("'{s}' is not a finite number ≥ 0")),
    }
}

fn parse_finite(s: &str) -> Result<f32, String> {
    match s.parse::<f32>() {
        Ok(v) if v.is_finite() => Ok(v),
        _ => Err(format!("'{s}' is not a finite number")),
    }
}

fn parse_fov(s: &str) -> Result<f32, String> {
    match s.parse::<f32>() {
        Ok(v) if v > 0.0 && v < 180.0 => Ok(v),
        _ => Err(format!("'{s}' is not a field of view in (0, 180) degrees")),
    }
}
