//! Validation report: on the held-out views of a dataset, compares the noisy input, the
//! denoiser with all of rtd's guide layers, the denoiser with only the guide RGB (the mode for
//! other software), the thesis's §6.4 ablation (the noisy image given as the guide), the
//! non-learned guided filter (its parameters chosen by grid search on the training views), and
//! optionally external results such as Intel OIDN's, all with the same metric code.

use std::path::Path;

use rtd_denoise::filter::GuidedFilter;
use rtd_denoise::{DenoiseInput, Denoiser};
use rtd_image::metrics::{metrics, Metrics};
use rtd_image::HdrImage;
use serde::Serialize;

use crate::data::{load_views, View};
use crate::{Progress, TrainError};

/// Border excluded from every metric, as in the benchmark.
pub const CROP: u32 = 8;

/// The methods compared, in table order.
pub const METHODS: [&str; 5] =
    ["noisy", "rtd (all guides)", "rtd (guide RGB only)", "ablation: noisy as guide", "guided filter"];

/// Metrics of every method on one view.
#[derive(Clone, Debug, Serialize)]
pub struct ViewResult {
    /// The view's file.
    pub view: String,
    /// (method, metrics) pairs.
    pub methods: Vec<(String, Metrics)>,
}

/// The whole report.
#[derive(Clone, Debug, Serialize)]
pub struct ValidationReport {
    /// Sample count of the noisy inputs.
    pub spp: u32,
    /// The model.
    pub model: String,
    /// The guided filter's parameters after the grid search.
    pub filter: GuidedFilter,
    /// Per-view results.
    pub views: Vec<ViewResult>,
    /// Means per method.
    pub mean: Vec<(String, Metrics)>,
}

fn mean_metrics(all: &[&Metrics]) -> Metrics {
    let n = all.len().max(1) as f64;
    let f = |g: fn(&Metrics) -> f64| all.iter().map(|m| g(m)).sum::<f64>() / n;
    Metrics {
        psnr: f(|m| m.psnr),
        ssim: f(|m| m.ssim),
        relmse: f(|m| m.relmse),
        smape: f(|m| m.smape),
        snr_db: f(|m| m.snr_db),
    }
}

/// Picks the guided filter's parameters that maximise mean PSNR on `views` at `spp`.
pub fn tune_filter(views: &[View], spp: u32) -> Result<GuidedFilter, TrainError> {
    let mut best = (f64::NEG_INFINITY, GuidedFilter::default());
    for sc in [0.25f32, 0.5, 1.0, 2.0, 4.0] {
        for sg in [0.02f32, 0.05, 0.1, 0.3, 1.0] {
            let f = GuidedFilter::default().sigma_color(sc).sigma_guide(sg);
            let mut total = 0.0;
            for v in views {
                total += rtd_image::metrics::psnr(&f.filter(&v.input(spp)?)?, &v.reference, CROP);
            }
            if total > best.0 {
                best = (total, f);
            }
        }
    }
    Ok(best.1)
}

/// Runs the comparison. `external` optionally names directories whose `<view>.exr` (the view's
/// file stem) holds another denoiser's output, added as a method named after the directory.
/// `save`, if given, is a directory that receives rtd's all-guides output of each view as
/// `<view>.exr` (`R,G,B`), the layout `external` reads, so two models' outputs can be compared
/// or inspected.
pub fn validation_report(
    data: &Path,
    model: &Denoiser,
    spp: u32,
    external: &[(String, std::path::PathBuf)],
    save: Option<&Path>,
    progress: &dyn Progress,
) -> Result<ValidationReport, TrainError> {
    let train = load_views(data, false)?;
    let val = load_views(data, true)?;
    progress.start(val.len() as u64 + 1, "evaluate");
    let filter = tune_filter(&train, spp)?;
    progress.inc(1);
    let mut views = vec![];
    for v in &val {
        let input = v.input(spp)?;
        let color = input.color;
        let guide_only = DenoiseInput::new(color, &v.guide);
        let ablation = DenoiseInput::new(color, color);
        let denoised = model.denoise(&input)?;
        let stem = Path::new(&v.record.file).file_stem().and_then(|s| s.to_str()).unwrap_or_default().to_string();
        if let Some(dir) = save {
            let mut layers = rtd_image::Layers::new(color.width, color.height);
            layers.push_rgb("", &denoised);
            rtd_image::write_exr(&dir.join(format!("{stem}.exr")), &layers)?;
        }
        let mut methods: Vec<(String, HdrImage)> = vec![
            (METHODS[0].into(), color.clone()),
            (METHODS[1].into(), denoised),
            (METHODS[2].into(), model.denoise(&guide_only)?),
            (METHODS[3].into(), model.denoise(&ablation)?),
            (METHODS[4].into(), filter.filter(&input)?),
        ];
        for (name, dir) in external {
            let path = dir.join(format!("{stem}.exr"));
            let layers = rtd_image::read_exr(&path)?;
            let img = layers.rgb("").ok_or_else(|| TrainError::msg(&path, "no R,G,B channels"))?;
            methods.push((name.clone(), img));
        }
        views.push(ViewResult {
            view: v.record.file.clone(),
            methods: methods.iter().map(|(n, img)| (n.clone(), metrics(img, &v.reference, CROP))).collect(),
        });
        progress.inc(1);
    }
    let names: Vec<String> =
        views.first().map(|v| v.methods.iter().map(|(n, _)| n.clone()).collect()).unwrap_or_default();
    let mean = names
        .iter()
        .enumerate()
        .map(|(k, n)| (n.clone(), mean_metrics(&views.iter().map(|v| &v.methods[k].1).collect::<Vec<_>>())))
        .collect();
    Ok(ValidationReport { spp, model: model.name().to_string(), filter, views, mean })
}

impl ValidationReport {
    /// A Markdown table of the means, plus the per-view PSNR.
    pub fn markdown(&self) -> String {
        let mut s = format!(
            "Validation views: {}, noisy input at {} spp, metrics with an {CROP}-px border cropped.\n\n",
            self.views.len(),
            self.spp
        );
        s += "| method | PSNR (dB) | SSIM | relMSE | SMAPE | SNR (dB) |\n|---|---|---|---|---|---|\n";
        for (n, m) in &self.mean {
            s += &format!(
                "| {n} | {:.2} | {:.4} | {:.4} | {:.4} | {:.2} |\n",
                m.psnr, m.ssim, m.relmse, m.smape, m.snr_db
            );
        }
        s += "\nPer view, PSNR (dB):\n\n| view |";
        for (n, _) in &self.mean {
            s += &format!(" {n} |");
        }
        s += "\n|---|";
        s += &"---|".repeat(self.mean.len());
        s += "\n";
        for v in &self.views {
            s += &format!("| {} |", v.view);
            for (_, m) in &v.methods {
                s += &format!(" {:.2} |", m.psnr);
            }
            s += "\n";
        }
        s
    }
}
