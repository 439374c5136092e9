//! `rtd bench`: thin wrappers over the library's benchmark reports.

use anyhow::Context;
use rtd_pipeline::{CameraChoice, SceneView};

use crate::args::{
    BenchArgs, BenchCommand, EtrtArgs, LightsArgs, PipelineArgs, ScalingArgs, ScenesArgs, SpeedArgs, SuiteArgs,
    ValidationArgs,
};
use crate::output::warn_all;
use crate::progress::TaskBar;
use rtd_image::write_json;

/// Runs `rtd bench …`.
pub fn bench(args: &BenchArgs) -> anyhow::Result<()> {
    match &args.which {
        BenchCommand::Validation(a) => validation(a),
        BenchCommand::Etrt(a) => etrt(a),
        BenchCommand::Suite(a) => suite(a),
        BenchCommand::Speed(a) => speed(a),
        BenchCommand::Scaling(a) => scaling(a),
        BenchCommand::Scenes(a) => scenes(a),
        BenchCommand::Lights(a) => lights(a),
    }
}

fn lights(args: &LightsArgs) -> anyhow::Result<()> {
    std::fs::create_dir_all(&args.output)
        .with_context(|| format!("{}: cannot create directory", args.output.display()))?;
    use rtd_bench::procedural::{write_scene, Family};
    let scenes = match &args.scene {
        Some(p) => vec![p.clone()],
        None => [Family::ManySmallLights, Family::LightHall]
            .iter()
            .map(|f| write_scene(&args.output.join("scenes"), f.name(), &f.scene()))
            .collect::<Result<_, _>>()?,
    };
    let mut md = String::new();
    let mut reports = vec![];
    for path in scenes {
        let view = load_first_camera(&path)?;
        let size = (args.width, args.height);
        let report = rtd_bench::light_selection::compare_light_selection(
            &view.scene.scene,
            &view.camera,
            size,
            args.seconds,
            args.reference_spp,
        )?;
        md += &format!("## {}\n\n{}\n", path.display(), report.markdown());
        reports.push(report);
    }
    write_json(&args.output.join("report.json"), &reports)?;
    rtd_image::write_bytes_atomic(&args.output.join("report.md"), md.as_bytes())?;
    crate::print_line(&md)?;
    Ok(())
}

fn scaling(args: &ScalingArgs) -> anyhow::Result<()> {
    use rtd_bench::scaling::{measure_point, run_scaling};
    // A point is checked before anything is made.
    let point = args.point.as_deref().map(parse_point).transpose()?;
    std::fs::create_dir_all(&args.output)
        .with_context(|| format!("{}: cannot create directory", args.output.display()))?;
    if let Some((axis, value)) = point {
        let model = crate::args::DenoiserArgs { model: args.model.clone(), ensemble: 1 }.load()?;
        let p = measure_point(axis, value, &args.output, &model, args.runs as usize)?;
        return crate::print_line(&serde_json::to_string(&p)?);
    }
    let exe = std::env::current_exe().context("cannot find the rtd executable to measure each point with")?;
    let bar = TaskBar::new(args.quiet);
    let report =
        run_scaling(&exe, &args.axes, args.quick, args.runs as usize, args.model.as_deref(), &args.output, &bar);
    bar.finish();
    crate::print_line(&report?.markdown())?;
    Ok(())
}

/// `AXIS=VALUE` of `--point`, with VALUE within the axis's range.
fn parse_point(point: &str) -> anyhow::Result<(rtd_bench::scaling::Axis, u64)> {
    let (axis, value) = point.split_once('=').context("--point takes AXIS=VALUE")?;
    let axis = rtd_bench::scaling::Axis::parse(axis).with_context(|| format!("unknown axis {axis:?}"))?;
    let value: u64 = value.parse().with_context(|| format!("--point: {value:?} is not a whole number"))?;
    let range = axis.range();
    anyhow::ensure!(range.contains(&value), "--point: {} {value} is outside {range:?}", axis.name());
    Ok((axis, value))
}

fn scenes(args: &ScenesArgs) -> anyhow::Result<()> {
    for path in rtd_bench::procedural::write_families(&args.output)? {
        crate::print_line(&path.display().to_string())?;
    }
    Ok(())
}

fn speed(args: &SpeedArgs) -> anyhow::Result<()> {
    let model = args.denoiser.load()?;
    let view = load_first_camera(&args.scene)?;
    let bar = TaskBar::new(args.quiet);
    let size = (args.width, args.height);
    let report = rtd_bench::speed::run_speed(&view, &model, size, args.spp, args.runs as usize, &bar);
    bar.finish();
    let report = report?;
    if let Some(p) = &args.report {
        write_json(p, &report)?;
    }
    crate::print_line(&report.markdown())?;
    Ok(())
}

fn suite(args: &SuiteArgs) -> anyhow::Result<()> {
    let model = args.pipeline.denoiser.load()?;
    let mut scenes = vec![];
    let inputs = if args.scenes.is_empty() {
        // The bundled scenes, as seen from the repository root.
        let bundled = std::path::PathBuf::from("scenes");
        anyhow::ensure!(bundled.is_dir(), "scenes: no such folder (run from the repository root, or name the scenes)");
        vec![bundled]
    } else {
        args.scenes.clone()
    };
    for p in inputs {
        if p.is_dir() {
            let mut found: Vec<_> = std::fs::read_dir(&p)
                .with_context(|| format!("{}: cannot list directory", p.display()))?
                .filter_map(|e| e.ok().map(|e| e.path()))
                .filter(|f| matches!(f.extension().and_then(|e| e.to_str()), Some("gltf" | "glb" | "obj")))
                .collect();
            found.sort();
            scenes.extend(found);
        } else {
            scenes.push(p);
        }
    }
    if scenes.is_empty() {
        anyhow::bail!("no scenes found (give .gltf/.glb/.obj files or directories)");
    }
    let options = etrt_options(&args.pipeline, 0);
    std::fs::create_dir_all(&args.output)
        .with_context(|| format!("{}: cannot create directory", args.output.display()))?;
    let bar = TaskBar::new(args.quiet);
    let results = rtd_bench::suite::run_suite(&scenes, &model, &options, &args.output, &bar);
    bar.finish();
    let results = results?;
    crate::print_line(&rtd_bench::suite::summary_markdown(&results))?;
    Ok(())
}

/// The measurement options both `etrt` and `suite` take from their arguments.
fn etrt_options(p: &PipelineArgs, seed: u64) -> rtd_bench::EtrtOptions {
    rtd_bench::EtrtOptions {
        spp: p.spp,
        width: p.width,
        height: p.height,
        seed,
        reference: rtd_bench::reference::ReferenceOptions::default()
            .spp(p.reference_spp)
            .relmse(p.reference_relmse)
            .max_spp(p.reference_max_spp),
        ..Default::default()
    }
}

fn etrt(args: &EtrtArgs) -> anyhow::Result<()> {
    let model = args.pipeline.denoiser.load()?;
    let options = etrt_options(&args.pipeline, args.seed);
    let view = load_first_camera(&args.scene)?;
    let bar = TaskBar::new(args.quiet);
    let cache = args.output.join("cache");
    let result = rtd_bench::run_etrt(&view, &model, &options, args.reference.as_deref(), &cache, &bar);
    bar.finish();
    let (report, images) = result?;
    rtd_bench::report_files::write_etrt(&args.output, &report, &images)?;
    crate::print_line(&report.markdown())?;
    Ok(())
}

fn validation(args: &ValidationArgs) -> anyhow::Result<()> {
    let model = args.denoiser.load()?;
    let bar = TaskBar::new(args.quiet);
    let report = rtd_bench::validation::validation_report(
        &args.data,
        &model,
        args.spp,
        &args.external,
        args.save_images.as_deref(),
        &bar,
    );
    bar.finish();
    let report = report?;
    std::fs::create_dir_all(&args.output)
        .with_context(|| format!("{}: cannot create directory", args.output.display()))?;
    write_json(&args.output.join("report.json"), &report)?;
    let md = report.markdown();
    rtd_image::write_bytes_atomic(&args.output.join("report.md"), md.as_bytes())?;
    crate::print_line(&md)?;
    Ok(())
}

/// Loads a benchmark scene with its first camera, printing its warnings.
fn load_first_camera(scene: &std::path::Path) -> anyhow::Result<SceneView> {
    let view = SceneView::load(scene, &CameraChoice::Default, None)?;
    warn_all(scene, view.warnings.iter().map(String::as_str));
    Ok(view)
}
