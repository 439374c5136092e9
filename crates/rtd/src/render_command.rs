//! `rtd render`: arguments to a [`Pipeline`] run, the image and the report written.

use std::time::Duration;

use rtd_guide::GuideSettings;
use rtd_image::Tonemap;
use rtd_pipeline::{Budget, Pipeline, RenderReport};
use rtd_render::RenderSettings;
use rtd_scene::EnvironmentChoice;

use crate::args::{RenderArgs, TonemapArg};
use crate::exit::Interrupted;
use crate::output::{check_output, check_report_path, warn_all};
use crate::progress::TaskBar;
use rtd_image::write_json;

/// Runs `rtd render` and returns its report.
pub fn render(args: &RenderArgs) -> anyhow::Result<RenderReport> {
    let view = &args.view;
    check_output(&args.output)?;
    if let Some(r) = &args.report {
        check_report_path(r)?;
    }
    // Load the model first: a bad model should fail before minutes of rendering.
    let model = if args.denoise { Some(args.denoiser().load()?) } else { None };
    let env = args
        .env
        .as_ref()
        .map(|e| EnvironmentChoice::new(e.as_str()).strength(args.env_strength).rotation_deg(args.env_rotation));
    let (loaded, (width, height)) = view.load(env.as_ref())?;
    let settings = RenderSettings::new(width, height)
        .seed(args.seed)
        .max_depth(args.max_depth)
        .clamp(args.clamp)
        .threads(view.threads.map(|t| t as usize));
    settings.validate()?;
    warn_all(&view.scene, loaded.lighting_warning());
    let mut pipeline = Pipeline::new(&loaded, settings.clone());
    if args.aov {
        pipeline = pipeline.guide(GuideSettings::new(width, height).threads(settings.threads));
    }
    if let Some(m) = &model {
        pipeline = pipeline.denoise(m);
    }
    let budget = match args.time {
        Some(secs) => Budget::Time(Duration::from_secs_f64(secs)),
        None => Budget::Samples(args.spp.unwrap_or(16)),
    };
    let bar = TaskBar::new(view.quiet);
    let run = pipeline.run(budget, &bar);
    bar.finish();
    let run = run?;
    let tonemap = match args.tonemap {
        TonemapArg::Clamp => Tonemap::Clamp,
        TonemapArg::Aces => Tonemap::Aces,
    };
    let report = RenderReport::new(&loaded, &settings, model.as_ref(), &run, &args.output);
    run.write_into(&args.output, args.exposure, tonemap)?;
    crate::print_line(&report.summary())?;
    if let Some(path) = &args.report {
        write_json(path, &report)?;
    }
    if report.interrupted {
        let kept = format!("{} spp of the image are written to {}", report.spp, args.output.display());
        return Err(Interrupted(kept).into());
    }
    Ok(report)
}
