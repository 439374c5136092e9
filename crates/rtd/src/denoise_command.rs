//! `rtd denoise`: the learned denoiser on images from any renderer, through
//! [`DenoiseSources`].

use rtd_pipeline::{DenoiseOutcome, DenoiseSources};

use crate::args::DenoiseArgs;
use crate::output::{check_output, check_report_path};
use rtd_image::{write_json, Layer};

/// Runs `rtd denoise` and returns its report.
pub fn denoise(args: &DenoiseArgs) -> anyhow::Result<DenoiseOutcome> {
    check_output(&args.output)?;
    if let Some(r) = &args.report {
        check_report_path(r)?;
    }
    let sources = DenoiseSources::new(&args.color)
        .guide(args.guide.clone())
        .albedo(args.albedo.clone())
        .normal(args.normal.clone())
        .layer(Layer::Beauty, args.layer_color.clone())
        .layer(Layer::Albedo, args.layer_albedo.clone())
        .layer(Layer::Normal, args.layer_normal.clone());
    sources.check()?;
    let model = args.denoiser.load()?;
    let outcome = sources.run(&model, &args.output, args.exposure)?;
    crate::print_line(&outcome.summary())?;
    if let Some(path) = &args.report {
        write_json(path, &outcome)?;
    }
    Ok(outcome)
}
