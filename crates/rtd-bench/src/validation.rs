//! Validation report: on the held-out views of a dataset, compares the noisy input, the
//! denoiser with all of rtd's guide layers, the denoiser with only the guide RGB (the mode for
//! other software), the denoiser with colour, albedo and normal only (OIDN's inputs), the
//! thesis's §6.4 ablation (the noisy image given as the guide), the non-learned guided filter
//! (its parameters chosen by grid search on the training views), and optionally external
//! results such as Intel OIDN's, all with the same metric code.

use std::path::{Path, PathBuf};

use rtd_denoise::filter::GuidedFilter;
use rtd_denoise::{DenoiseInput, Denoiser};
use rtd_image::metrics::{metrics, Metrics};
use rtd_image::{HdrImage, Layer, Layers, Progress};
use rtd_train::data::{load_views, View};
use rtd_train::dataset::Manifest;
use serde::Serialize;

use crate::{BenchError, METRIC_BORDER};

/// A method the validation benchmark compares.
#[derive(Clone, Debug, PartialEq, Eq, Serialize)]
#[serde(into = "String")]
pub enum Method {
    /// The noisy input itself.
    Noisy,
    /// rtd's denoiser with every guide layer.
    AllGuides,
    /// rtd's denoiser with only the guide RGB (the mode for other software's renders).
    GuideRgbOnly,
    /// rtd's denoiser with colour, albedo and normal only, the albedo standing in for the
    /// guide: what OIDN is given, and what files from Blender or Nuke hold.
    AlbedoNormal,
    /// The thesis's §6.4 ablation: the noisy image given as the guide.
    NoisyAsGuide,
    /// The non-learned guided filter, tuned on the training views.
    GuidedFilter,
    /// Another denoiser's saved outputs, by the name given on the command line.
    External(String),
}

impl Method {
    /// The label tables and reports use.
    pub fn label(&self) -> &str {
        match self {
            Method::Noisy => "noisy",
            Method::AllGuides => "rtd (all guides)",
            Method::GuideRgbOnly => "rtd (guide RGB only)",
            Method::AlbedoNormal => "rtd (albedo + normal, as OIDN)",
            Method::NoisyAsGuide => "ablation: noisy as guide",
            Method::GuidedFilter => "guided filter",
            Method::External(name) => name,
        }
    }
}

impl From<Method> for String {
    fn from(m: Method) -> String {
        m.label().to_string()
    }
}

/// Metrics of every method on one view.
#[derive(Clone, Debug, Serialize)]
pub struct ViewResult {
    /// The view's file.
    pub view: String,
    /// (method, metrics) pairs, in the report's method order.
    pub methods: Vec<(Method, Metrics)>,
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
    pub mean: Vec<(Method, Metrics)>,
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
pub fn tune_filter(views: &[View], spp: u32) -> Result<GuidedFilter, BenchError> {
    let mut best = (f64::NEG_INFINITY, GuidedFilter::default());
    for sc in [0.25f32, 0.5, 1.0, 2.0, 4.0] {
        for sg in [0.02f32, 0.05, 0.1, 0.3, 1.0] {
            let f = GuidedFilter::default().sigma_color(sc).sigma_guide(sg);
            let mut total = 0.0;
            for v in views {
                total += rtd_image::metrics::psnr(&f.filter(&v.input(spp)?)?, &v.reference, METRIC_BORDER);
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
    external: &[(String, PathBuf)],
    save: Option<&Path>,
    progress: &dyn Progress,
) -> Result<ValidationReport, BenchError> {
    let manifest = Manifest::load(data)?;
    if !manifest.noisy_spp.contains(&spp) {
        let have: Vec<String> = manifest.noisy_spp.iter().map(u32::to_string).collect();
        return Err(BenchError::msg(
            data,
            format!("has no noisy render at {spp} spp (it has {} spp)", have.join(", ")),
        ));
    }
    if let Some(dir) = save {
        std::fs::create_dir_all(dir).map_err(|e| BenchError::io(dir, e))?;
    }
    let train = load_views(data, false)?;
    let val = load_views(data, true)?;
    progress.start(val.len() as u64 + 1, "evaluate");
    let filter = tune_filter(&train, spp)?;
    progress.inc(1);
    let mut views = vec![];
    for v in &val {
        let input = v.input(spp)?;
        let color = input.color;
        // Other software's inputs, read as `rtd denoise` reads such files.
        let guide_only = DenoiseInput::with_stand_in_guide(color, Some(&v.guide), None, None);
        let as_oidn = DenoiseInput::with_stand_in_guide(color, None, Some(&v.albedo), Some(&v.normal));
        let ablation = DenoiseInput::with_stand_in_guide(color, None, None, None);
        let denoised = model.denoise(&input)?;
        let stem = Path::new(&v.record.file).file_stem().and_then(|s| s.to_str()).unwrap_or_default().to_string();
        if let Some(dir) = save {
            let mut layers = Layers::new(color.width, color.height);
            layers.put_image(Layer::Beauty, &denoised);
            rtd_image::write_exr(&dir.join(format!("{stem}.exr")), &layers)?;
        }
        let mut methods: Vec<(Method, HdrImage)> = vec![
            (Method::Noisy, color.clone()),
            (Method::AllGuides, denoised),
            (Method::GuideRgbOnly, model.denoise(&guide_only)?),
            (Method::AlbedoNormal, model.denoise(&as_oidn)?),
            (Method::NoisyAsGuide, model.denoise(&ablation)?),
            (Method::GuidedFilter, filter.filter(&input)?),
        ];
        for (name, dir) in external {
            let path = dir.join(format!("{stem}.exr"));
            let layers = rtd_image::read_exr(&path)?;
            let img = layers.image(Layer::Beauty).ok_or_else(|| BenchError::msg(&path, "no R,G,B channels"))?;
            let (w, h) = (v.reference.width, v.reference.height);
            if (img.width, img.height) != (w, h) {
                let message = format!("image is {}x{} but the view is {w}x{h}", img.width, img.height);
                return Err(BenchError::msg(&path, message));
            }
            methods.push((Method::External(name.clone()), img));
        }
        views.push(ViewResult {
            view: v.record.file.clone(),
            methods: methods.into_iter().map(|(n, img)| (n, metrics(&img, &v.reference, METRIC_BORDER))).collect(),
        });
        progress.inc(1);
    }
    let names: Vec<Method> =
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
            "Validation views: {}, noisy input at {} spp, metrics with an {METRIC_BORDER}-px border cropped.\n\n",
            self.views.len(),
            self.spp
        );
        s += "| method | PSNR (dB) | SSIM | relMSE | SMAPE | SNR (dB) |\n|---|---|---|---|---|---|\n";
        for (n, m) in &self.mean {
            s += &format!(
                "| {} | {:.2} | {:.4} | {:.4} | {:.4} | {:.2} |\n",
                n.label(),
                m.psnr,
                m.ssim,
                m.relmse,
                m.smape,
                m.snr_db
            );
        }
        s += "\nPer view, PSNR (dB):\n\n| view |";
        for (n, _) in &self.mean {
            s += &format!(" {} |", n.label());
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
