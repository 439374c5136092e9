//! Dataset generation and training, end to end on tiny sizes: resumable datagen with a
//! by-scene split, `rtd train --quick` lowering its loss, deterministic and resumable training,
//! fine-tuning a trained network, and options refused before anything is written.

use std::path::Path;
use std::process::Command;

use rtd::image::Quiet;
use rtd::render::SPP_LADDER;
use rtd::train::dataset::{generate_dataset, DatasetOptions, Manifest, Split, ViewRecord};
use rtd::train::train::train;
use rtd::train::TrainError;
use rtd::train::TrainOptions;

fn tiny_dataset(dir: &Path) -> Manifest {
    let options = DatasetOptions::default().scenes(3).views_per_scene(1).size(24).reference_spp(16).validation_every(3);
    generate_dataset(dir, &options, &Quiet).unwrap()
}

/// A two-level, 8-channel network: enough to train in a test.
fn tiny_config() -> rtd::denoise::DenoiserConfig {
    rtd::denoise::DenoiserConfig::new(vec![8, 8]).with_bottleneck_blocks(1)
}

/// What the model saved in `run_dir` computes on a fixed 8×8 input.
fn saved_model_output(run_dir: &Path) -> Vec<f32> {
    let m = rtd::denoise::Denoiser::load(&run_dir.join("model.bpk")).unwrap();
    let planes: Vec<f32> = (0..rtd::denoise::INPUT_CHANNELS * 64).map(|i| (i % 7) as f32 * 0.1).collect();
    m.run_planes(&planes, 8, 8)
}

#[test]
fn datagen_resumes_without_redoing_views_and_splits_by_scene() {
    let dir = tempfile::tempdir().unwrap();
    let first = tiny_dataset(dir.path());
    assert_eq!(first.views.len() + first.rejected.len(), 3);
    let stamp = |m: &Manifest| {
        m.views
            .iter()
            .map(|v| std::fs::metadata(dir.path().join(&v.file)).unwrap().modified().unwrap())
            .collect::<Vec<_>>()
    };
    let before = stamp(&first);
    let again = tiny_dataset(dir.path());
    assert_eq!(stamp(&again), before, "finished views must not be rendered again");
    for v in &again.views {
        assert_eq!(v.validation, v.scene % 3 == 2, "split is by scene index");
        assert!(v.reference_relmse.is_finite() && v.reference_relmse >= 0.0);
        let layers = rtd::image::read_exr(&dir.path().join(&v.file)).unwrap();
        for spp in [1, 2, 4, 8, 16, 32, 64] {
            assert!(layers.image(rtd::image::Layer::NoisyAt(spp)).is_some());
        }
        for l in ["reference.R", "guide.R", "albedo.R", "normal.X", "ao.Y", "depth.Z"] {
            assert!(layers.get(l).is_some(), "{l}");
        }
    }
    // The generated glTF renders with the normal loader.
    assert!(rtd::scene::load_scene(&dir.path().join("scenes/scene0000.gltf")).is_ok());

    // More scenes extend the dataset in place; any other changed option is refused.
    let grown = DatasetOptions::default().scenes(4).views_per_scene(1).size(24).reference_spp(16).validation_every(3);
    let extended = generate_dataset(dir.path(), &grown, &Quiet).unwrap();
    assert_eq!(extended.views.len() + extended.rejected.len(), 4);
    assert_eq!(stamp(&again), before, "extending must not render the old views again");
    assert_eq!(Manifest::load(dir.path()).unwrap().options.scenes, 4);
    let bigger = grown.clone().size(32);
    let err = generate_dataset(dir.path(), &bigger, &Quiet).unwrap_err().to_string();
    assert!(err.contains("manifest.json") && err.contains("other options"), "{err}");
}

#[test]
fn a_split_renders_only_its_scenes_and_the_same_views() {
    let dir = tempfile::tempdir().unwrap();
    let (all_dir, val_dir, train_dir) = (dir.path().join("all"), dir.path().join("val"), dir.path().join("train"));
    let options = DatasetOptions::default().scenes(3).views_per_scene(1).size(24).reference_spp(16).validation_every(3);
    let all = generate_dataset(&all_dir, &options, &Quiet).unwrap();
    let val = generate_dataset(&val_dir, &options.clone().split(Split::Validation), &Quiet).unwrap();
    let train = generate_dataset(&train_dir, &options.clone().split(Split::Training), &Quiet).unwrap();
    let scenes = |m: &Manifest| {
        let mut s: Vec<u64> = m.views.iter().map(|v| v.scene).collect();
        s.extend(m.rejected.iter().map(|r| r.split('/').next().unwrap().parse::<u64>().unwrap()));
        s.sort();
        s
    };
    assert_eq!((scenes(&all), scenes(&val), scenes(&train)), (vec![0, 1, 2], vec![2], vec![0, 1]));
    assert!(!val.views.is_empty() && !train.views.is_empty(), "the byte comparison needs views");
    for (dir, m) in [(&val_dir, &val), (&train_dir, &train)] {
        for v in &m.views {
            assert_eq!(v.validation, v.scene == 2);
            let bytes = std::fs::read(dir.join(&v.file)).unwrap();
            assert_eq!(
                bytes,
                std::fs::read(all_dir.join(&v.file)).unwrap(),
                "{} differs from the full dataset's",
                v.file
            );
        }
    }
}

#[test]
fn quick_training_lowers_the_loss_and_writes_a_model_and_curves() {
    let dir = tempfile::tempdir().unwrap();
    let (data, out) = (dir.path().join("data"), dir.path().join("run"));
    let o = Command::new(env!("CARGO_BIN_EXE_rtd"))
        .args(["train", "--quick", "--data", data.to_str().unwrap(), "-o", out.to_str().unwrap(), "-q"])
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let state: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("state.json")).unwrap()).unwrap();
    let losses: Vec<f64> = state["losses"].as_array().unwrap().iter().map(|v| v.as_f64().unwrap()).collect();
    let k = losses.len() / 4;
    let (early, late) =
        (losses[..k].iter().sum::<f64>() / k as f64, losses[losses.len() - k..].iter().sum::<f64>() / k as f64);
    assert!(late < early * 0.95, "loss did not go down: {early} → {late}");
    let last = format!("checkpoints/{:08}", state["step"].as_u64().unwrap());
    for f in ["model.bpk", "model.json", "curves.png", &format!("{last}/weights.bpk"), &format!("{last}/optimizer.bpk")]
    {
        assert!(out.join(f).exists(), "{f}");
    }
    let kept = std::fs::read_dir(out.join("checkpoints")).unwrap().count();
    assert_eq!(kept, 1, "only the last checkpoint is kept");
    // The trained model loads and denoises.
    assert!(rtd::denoise::Denoiser::load(&out.join("model.bpk")).is_ok());
}

/// Progress that asks training to stop once `limit` steps are done (a user's Ctrl-C, on cue),
/// and, when watching a file, notes whether it existed at that moment.
struct StopAt {
    done: std::sync::atomic::AtomicU64,
    limit: u64,
    watched: Option<std::path::PathBuf>,
    seen: std::sync::Mutex<Option<bool>>,
}

impl StopAt {
    fn steps(limit: u64) -> Self {
        StopAt { done: 0.into(), limit, watched: None, seen: None.into() }
    }
    fn watching(self, file: std::path::PathBuf) -> Self {
        StopAt { watched: Some(file), ..self }
    }
}

impl rtd::image::Progress for StopAt {
    fn inc(&self, n: u64) {
        self.done.fetch_add(n, std::sync::atomic::Ordering::SeqCst);
    }
    fn cancelled(&self) -> bool {
        let stop = self.done.load(std::sync::atomic::Ordering::SeqCst) >= self.limit;
        if let (true, Some(file)) = (stop, &self.watched) {
            self.seen.lock().unwrap().get_or_insert(file.exists());
        }
        stop
    }
}

#[test]
fn training_is_deterministic_and_resuming_matches_an_uninterrupted_run() {
    let dir = tempfile::tempdir().unwrap();
    let data = dir.path().join("data");
    tiny_dataset(&data);
    let options = TrainOptions::default().config(tiny_config()).batch(2, 16).steps(6).epoch_steps(3);
    let a = train(&data, &dir.path().join("a"), &options, false, &Quiet).unwrap();
    let b = train(&data, &dir.path().join("b"), &options, false, &Quiet).unwrap();
    assert_eq!(a.losses, b.losses, "same seed, same losses");
    // Stop after the first epoch (3 steps), then resume. The curves are on disk as soon as
    // the epoch's checkpoint is (a run killed later keeps them).
    let c_dir = dir.path().join("c");
    let stop = StopAt::steps(3).watching(c_dir.join("curves.png"));
    let partial = train(&data, &c_dir, &options, false, &stop).unwrap();
    assert_eq!(partial.step, 3);
    assert_eq!(*stop.seen.lock().unwrap(), Some(true), "curves.png was not written with the first epoch");
    assert!(train(&data, &c_dir, &options, false, &Quiet).is_err(), "an existing run needs --resume");
    let other = options.clone().steps(7).validation_data(Some(data.clone()));
    let e = train(&data, &c_dir, &other, true, &Quiet).unwrap_err().to_string();
    assert!(e.contains("other training options (they differ in: steps, validation_data)"), "{e}");
    let resumed = train(&data, &c_dir, &options, true, &Quiet).unwrap();
    assert_eq!(resumed.step, 6);
    assert_eq!(resumed.losses, a.losses, "a resumed run continues exactly");
    // The resumed model computes exactly what the uninterrupted one does.
    let run = |d: &str| saved_model_output(&dir.path().join(d));
    assert!(run("a") == run("c"), "resumed weights differ");
    // Every file is the same bytes, so a reproduced model can be checked by its hash (burn's
    // random parameter ids and hash-map order used to change the headers and the layout).
    let bytes = |d: &str, f: &str| std::fs::read(dir.path().join(d).join(f)).unwrap();
    for f in ["model.bpk", "model.json", "checkpoints/00000006/weights.bpk", "checkpoints/00000006/optimizer.bpk"] {
        assert!(bytes("a", f) == bytes("b", f), "two identical runs wrote different {f}");
        assert!(bytes("a", f) == bytes("c", f), "the resumed run wrote a different {f}");
    }
}

/// A damaged checkpoint (disk error, a copy cut short) stops a resume with an error naming the
/// file, not a panic in burn's record reader.
#[test]
fn a_damaged_checkpoint_is_named_when_resuming() {
    let dir = tempfile::tempdir().unwrap();
    let data = dir.path().join("data");
    tiny_dataset(&data);
    let options = TrainOptions::default().config(tiny_config()).batch(2, 16).steps(4).epoch_steps(2);
    // Stopped after the first epoch (2 steps), which leaves a checkpoint.
    let run = dir.path().join("run");
    let partial = train(&data, &run, &options, false, &StopAt::steps(2)).unwrap();
    assert_eq!(partial.step, 2);
    let checkpoint = run.join(format!("checkpoints/{:08}", partial.step));
    for (file, bytes) in [("weights.bpk", &b"\x00not burnpack"[..]), ("optimizer.bpk", &b""[..])] {
        let path = checkpoint.join(file);
        let whole = std::fs::read(&path).unwrap();
        std::fs::write(&path, bytes).unwrap();
        let e = train(&data, &run, &options, true, &Quiet).expect_err("a damaged checkpoint must be refused");
        assert!(e.to_string().starts_with(&path.display().to_string()), "{e}");
        assert!(!e.to_string().contains('\n'), "{e}");
        std::fs::write(&path, whole).unwrap();
    }
    assert_eq!(train(&data, &run, &options, true, &Quiet).unwrap().step, 4, "the mended run resumes");
}

#[test]
fn fine_tuning_starts_from_the_given_model_and_checks_its_config() {
    let dir = tempfile::tempdir().unwrap();
    let data = dir.path().join("data");
    tiny_dataset(&data);
    let options = TrainOptions::default().config(tiny_config()).batch(2, 16).steps(4).epoch_steps(4);
    let a = train(&data, &dir.path().join("a"), &options, false, &Quiet).unwrap();
    let a_model = dir.path().join("a/model.bpk");
    // Training on the 8-spp renders alone, always with every guide layer, sees other batches;
    // sample counts the dataset lacks are refused, naming its manifest.
    let focused = options.clone().spp_levels(Some(vec![8])).guide_drop(0.0);
    let f = train(&data, &dir.path().join("f"), &focused, false, &Quiet).unwrap();
    assert!(f.losses.len() == a.losses.len() && f.losses != a.losses);
    let absent = options.clone().spp_levels(Some(vec![3]));
    let err = train(&data, &dir.path().join("s"), &absent, false, &Quiet).unwrap_err().to_string();
    assert!(err.starts_with(&format!("{}: ", data.display())) && err.contains("sample counts"), "{err}");
    // Also when only some are absent, and before the run directory is made.
    let partly = options.clone().spp_levels(Some(vec![3, 8]));
    let err = train(&data, &dir.path().join("p"), &partly, false, &Quiet).unwrap_err().to_string();
    assert!(err.contains("[3]") && !dir.path().join("p").exists(), "{err}");
    // One step at a negligible rate from a's weights: the result computes what a does, and
    // differs from a fresh network.
    let tuned = options.clone().steps(1).learning_rate(1e-12).init(Some(a_model.clone()));
    train(&data, &dir.path().join("b"), &tuned, false, &Quiet).unwrap();
    let fresh = options.clone().steps(1).learning_rate(1e-12).seed(9);
    train(&data, &dir.path().join("c"), &fresh, false, &Quiet).unwrap();
    let run = |d: &str| saved_model_output(&dir.path().join(d));
    let diff = |x: &[f32], y: &[f32]| x.iter().zip(y).map(|(p, q)| (p - q).abs()).fold(0.0, f32::max);
    assert!(diff(&run("a"), &run("b")) < 1e-4, "fine-tuning did not start from the given weights");
    assert!(diff(&run("a"), &run("c")) > 1e-3, "a fresh network should differ");
    // A model without demodulation may seed a demodulating run of the same shape, which then
    // says so in its config; so may it seed one that takes another exposure key.
    let encoding = tiny_config().with_demodulate(Some(true)).with_exposure_key(Some(1.44));
    train(&data, &dir.path().join("e"), &tuned.clone().config(encoding), false, &Quiet).unwrap();
    let cfg = std::fs::read_to_string(dir.path().join("e/model.json")).unwrap();
    let cfg = rtd::denoise::DenoiserConfig::from_json(&cfg).unwrap();
    assert!(cfg.demodulates() && cfg.exposure_key() == 1.44);
    // A direct-prediction model seeds a kernel-predicting run (new heads, drawn from the seed),
    // whose model says so, loads and denoises to something else than its seed computes.
    let kernels = tuned.clone().config(tiny_config().with_kernel_output(Some(true)));
    train(&data, &dir.path().join("k"), &kernels, false, &Quiet).unwrap();
    let cfg = std::fs::read_to_string(dir.path().join("k/model.json")).unwrap();
    assert!(rtd::denoise::DenoiserConfig::from_json(&cfg).unwrap().predicts_kernels());
    let k = run("k");
    assert!(k.iter().all(|v| v.is_finite()) && diff(&run("a"), &k) > 1e-3);
    // Not the other way: a kernel-predicting model cannot seed a direct run.
    let back = tuned.clone().init(Some(dir.path().join("k/model.bpk")));
    let err = train(&data, &dir.path().join("kd"), &back, false, &Quiet).unwrap_err().to_string();
    assert!(err.contains("another network"), "{err}");
    // Wider kernels: the model's config keeps their size, and it denoises to something else
    // than the 5×5 heads drawn from the same seed; a 5×5 model cannot seed a 7×7 run.
    let wide = tiny_config().with_kernel_output(Some(true)).with_kernel_size(Some(7));
    train(&data, &dir.path().join("k7"), &tuned.clone().config(wide.clone()), false, &Quiet).unwrap();
    let cfg = std::fs::read_to_string(dir.path().join("k7/model.json")).unwrap();
    assert_eq!(rtd::denoise::DenoiserConfig::from_json(&cfg).unwrap().kernel_size(), 7);
    let k7 = run("k7");
    assert!(k7.iter().all(|v| v.is_finite()) && diff(&k, &k7) > 1e-3);
    let narrow = tuned.clone().config(wide).init(Some(dir.path().join("k/model.bpk")));
    let err = train(&data, &dir.path().join("k75"), &narrow, false, &Quiet).unwrap_err().to_string();
    assert!(err.contains("another network"), "{err}");
    // A model of another shape is refused, naming its config file.
    let other = options.clone().config(rtd::denoise::DenoiserConfig::new(vec![8])).init(Some(a_model));
    let err = train(&data, &dir.path().join("d"), &other, false, &Quiet).unwrap_err().to_string();
    assert!(err.contains("model.json") && err.contains("another network"), "{err}");
}

#[test]
fn a_model_without_the_variance_planes_seeds_a_run_that_reads_them() {
    // A model made before the variance planes reads the 16 legacy planes (one is trained here:
    // the shipped model reads all 20). One step at a negligible rate from it trains the
    // full-width network, which must compute what the legacy model computes.
    let dir = tempfile::tempdir().unwrap();
    let data = dir.path().join("data");
    tiny_dataset(&data);
    let legacy_config = tiny_config().with_input_channels(rtd::denoise::planes::LEGACY_INPUT_CHANNELS);
    let options = TrainOptions::default().batch(1, 16).steps(1).epoch_steps(1);
    train(&data, &dir.path().join("legacy"), &options.clone().config(legacy_config.clone()), false, &Quiet).unwrap();
    let legacy_path = dir.path().join("legacy/model.bpk");
    let legacy = rtd::denoise::Denoiser::load(&legacy_path).unwrap();
    assert!(!legacy.reads_variance());
    let config = legacy_config.with_input_channels(rtd::denoise::INPUT_CHANNELS);
    let widen = options.config(config).learning_rate(1e-12).init(Some(legacy_path));
    train(&data, &dir.path().join("w"), &widen, false, &Quiet).unwrap();
    let widened = rtd::denoise::Denoiser::load(&dir.path().join("w/model.bpk")).unwrap();
    assert!(widened.reads_variance());
    let planes: Vec<f32> = (0..rtd::denoise::INPUT_CHANNELS * 64).map(|i| (i % 7) as f32 * 0.1).collect();
    let (a, b) = (legacy.run_planes(&planes, 8, 8), widened.run_planes(&planes, 8, 8));
    let diff = a.iter().zip(&b).map(|(p, q)| (p - q).abs()).fold(0.0, f32::max);
    assert!(diff < 1e-4, "the widened network computes something else: {diff}");
    // And it is not trivially so: the variance planes reach the widened network's output once
    // its stem weights for them are not zero (here: after training at a real rate).
    let trained = TrainOptions::default().batch(1, 16).steps(3).epoch_steps(3).learning_rate(1e-2).variance_drop(0.0);
    let trained = trained.config(widen.config.clone()).init(Some(dir.path().join("w/model.bpk")));
    train(&data, &dir.path().join("t"), &trained, false, &Quiet).unwrap();
    let t = rtd::denoise::Denoiser::load(&dir.path().join("t/model.bpk")).unwrap();
    let mut other = planes.clone();
    other[16 * 64..].iter_mut().for_each(|v| *v += 0.5);
    assert_ne!(t.run_planes(&planes, 8, 8), t.run_planes(&other, 8, 8));
}

/// A dataset directory holding only a manifest that lists a training and a validation view of
/// `size`² pixels which were never rendered: enough for the option checks, which come before
/// any view is read.
fn manifest_only(dir: &Path, size: u32) {
    let view = |scene: u64, validation: bool| ViewRecord {
        file: format!("views/scene{scene:04}_v0.exr"),
        scene,
        view: 0,
        layout: rtd::train::scenegen::Layout::ClosedRoom,
        validation,
        reference_spp: 16,
        reference_relmse: 0.0,
        seconds: 0.0,
    };
    let manifest = Manifest {
        options: DatasetOptions::default().size(size),
        noisy_spp: SPP_LADDER.to_vec(),
        views: vec![view(0, false), view(5, true)],
        rejected: vec![],
    };
    std::fs::create_dir_all(dir).unwrap();
    std::fs::write(dir.join("manifest.json"), serde_json::to_string(&manifest).unwrap()).unwrap();
}

#[test]
fn options_the_dataset_cannot_serve_are_refused_before_anything_is_read_or_written() {
    let dir = tempfile::tempdir().unwrap();
    let (data, out) = (dir.path().join("data"), dir.path().join("run"));
    manifest_only(&data, 24);
    let refusal = |options: &TrainOptions| match train(&data, &out, options, false, &Quiet) {
        Err(e @ TrainError::InvalidOptions { .. }) => e.to_string(),
        Err(e) => panic!("expected InvalidOptions, got {e}"),
        Ok(_) => panic!("trained with {options:?}"),
    };
    // The U-Net aligns to 4 px: 32 is aligned but larger than the views, 18 smaller but not aligned.
    let too_large = "crop side 32 px is larger than the dataset's 24x24 px views";
    for (crop, why) in [(32, too_large), (18, "not a positive multiple of 4")] {
        let e = refusal(&TrainOptions::default().batch(2, crop));
        assert!(e.starts_with(&format!("{}: ", data.display())) && e.contains(why) && !e.contains('\n'), "{e}");
        assert!(!out.exists(), "a refused run made {}", out.display());
    }
    // Options within those limits get as far as reading the views, which this dataset lacks.
    let e = train(&data, &out, &TrainOptions::default().batch(2, 24), false, &Quiet).unwrap_err().to_string();
    assert!(e.contains("scene0000_v0.exr") && e.contains("no such file"), "{e}");
}

/// A training set made with `--split training` has no validation views; `validation_data`
/// scores every epoch on another dataset's instead, and is refused, before anything is
/// written, when that dataset has none.
#[test]
fn a_separate_validation_set_scores_the_epochs() {
    let dir = tempfile::tempdir().unwrap();
    let (train_set, held_out) = (dir.path().join("train"), dir.path().join("held-out"));
    let make = |path: &Path, split| {
        let options = DatasetOptions::default().scenes(3).views_per_scene(1).size(24).reference_spp(16);
        generate_dataset(path, &options.validation_every(3).split(split), &Quiet).unwrap()
    };
    assert!(make(&train_set, Split::Training).views.iter().all(|v| !v.validation));
    assert!(make(&held_out, Split::Validation).views.iter().all(|v| v.validation));
    let options = TrainOptions::default().config(tiny_config()).batch(2, 16).steps(2).epoch_steps(2);
    let own = train(&train_set, &dir.path().join("own"), &options, false, &Quiet).unwrap();
    assert_eq!(own.history[0].validation, None, "a training split has no validation views");
    let scored = options.clone().validation_data(Some(held_out.clone()));
    let run = train(&train_set, &dir.path().join("scored"), &scored, false, &Quiet).unwrap();
    let v = run.history[0].validation.expect("scored on the held-out views");
    assert!(v.psnr.is_finite() && v.noisy_psnr > 0.0, "{v:?}");
    // The same network scored on the same views by the library's own function.
    let views = rtd::train::data::load_views(&held_out, true).unwrap();
    let model = rtd::denoise::Denoiser::load(&dir.path().join("scored").join("model.bpk")).unwrap();
    let again = rtd::train::train::validation_scores(&model, &views, 8).unwrap();
    assert!((again.psnr - v.psnr).abs() < 1e-6 && again.noisy_psnr == v.noisy_psnr, "{again:?} vs {v:?}");
    // A validation set without validation views is refused, naming it, and nothing is written.
    let out = dir.path().join("refused");
    let e = train(&held_out, &out, &options, false, &Quiet).unwrap_err().to_string();
    assert!(e.contains("no training views"), "a validation split has nothing to train on: {e}");
    let e = train(&train_set, &out, &options.clone().validation_data(Some(train_set.clone())), false, &Quiet)
        .unwrap_err()
        .to_string();
    assert!(e.starts_with(&format!("{}: ", train_set.display())) && e.contains("no validation views"), "{e}");
    assert!(!out.exists());
}

/// `more_data` pools other datasets' training views with the training dataset's: the pooled
/// run trains on another set of views than the single one (its model differs) and is as
/// deterministic; a pooled dataset the options cannot serve is refused by name before anything
/// is written; and the datasets are part of the run's options, so a resume must name them again.
#[test]
fn more_datasets_pool_their_training_views() {
    let dir = tempfile::tempdir().unwrap();
    let make = |name: &str, seed: u64, size: u32| {
        let path = dir.path().join(name);
        let options = DatasetOptions::default().seed(seed).scenes(3).views_per_scene(1).size(size).reference_spp(16);
        generate_dataset(&path, &options.validation_every(3), &Quiet).unwrap();
        path
    };
    let (a, b, small) = (make("a", 1, 24), make("b", 2, 24), make("small", 3, 16));
    let options = TrainOptions::default().config(tiny_config()).batch(2, 24).steps(4).epoch_steps(2);
    let run = |name: &str, more: Vec<std::path::PathBuf>| {
        train(&a, &dir.path().join(name), &options.clone().more_data(more), false, &Quiet)
    };
    let alone = run("alone", vec![]).unwrap();
    let pooled = run("pooled", vec![b.clone()]).unwrap();
    let again = run("again", vec![b.clone()]).unwrap();
    assert_eq!(pooled.losses, again.losses, "same datasets, same seed, same losses");
    assert_ne!(alone.losses, pooled.losses, "the pooled run trained on the same crops as the single one");
    let output = |d: &str| saved_model_output(&dir.path().join(d));
    assert!(output("alone") != output("pooled"));
    // 16² views cannot serve 24² crops: refused, naming that dataset, and nothing is written.
    let e = run("refused", vec![b.clone(), small.clone()]).unwrap_err().to_string();
    assert!(e.starts_with(&format!("{}: ", small.display())) && e.contains("crop side 24"), "{e}");
    assert!(!dir.path().join("refused").exists());
    // A resume without the pooled dataset names the option that differs.
    let e = train(&a, &dir.path().join("pooled"), &options.clone().steps(4), true, &Quiet).unwrap_err().to_string();
    assert!(e.contains("(they differ in: more_data)"), "{e}");
}

/// `refresh_guides` re-renders exactly the guide layers of every view and keeps the rest.
#[test]
fn refreshing_guides_rewrites_guide_layers_only() {
    let dir = tempfile::tempdir().unwrap();
    let manifest = tiny_dataset(dir.path());
    let file = dir.path().join(&manifest.views[0].file);
    let original = rtd::image::read_exr(&file).unwrap();
    // Stale guide layers, as a dataset made by an older guide pass has.
    let mut stale = original.clone();
    for name in ["albedo.R", "guide.G", "ao.Y", "depth.Z", "normal.X"] {
        stale.push(name, vec![0.123; (stale.width * stale.height) as usize]);
    }
    rtd::image::write_exr(&file, &stale).unwrap();
    let n = rtd::train::dataset::refresh_guides(dir.path(), &Quiet).unwrap();
    assert_eq!(n, manifest.views.len());
    let refreshed = rtd::image::read_exr(&file).unwrap();
    for name in ["albedo.R", "guide.G", "ao.Y", "depth.Z", "normal.X", "noisy8.R", "reference.B"] {
        assert_eq!(refreshed.get(name), original.get(name), "{name}");
    }
}

/// `rtd bench validation --save-images`: one EXR per validation view, and those images, read
/// back as an external method, score exactly what the report gives rtd with all guides.
#[test]
fn validation_saves_rtd_outputs_that_score_as_reported() {
    let dir = tempfile::tempdir().unwrap();
    let data = dir.path().join("data");
    let manifest = tiny_dataset(&data);
    let saved = dir.path().join("saved");
    std::fs::create_dir_all(&saved).unwrap();
    let model = rtd::denoise::Denoiser::builtin().unwrap();
    let report =
        rtd::bench::validation::validation_report(&data, &model, 8, &[], Some(saved.as_path()), &Quiet).unwrap();
    let validation: Vec<_> = manifest.views.iter().filter(|v| v.validation).collect();
    assert_eq!(report.views.len(), validation.len());
    assert_eq!(std::fs::read_dir(&saved).unwrap().count(), validation.len());
    let external = vec![("saved".to_string(), saved.clone())];
    let again = rtd::bench::validation::validation_report(&data, &model, 8, &external, None, &Quiet).unwrap();
    for v in &again.views {
        use rtd::bench::validation::Method;
        let psnr = |m: Method| v.methods.iter().find(|(n, _)| *n == m).unwrap().1.psnr;
        let saved = || Method::External("saved".into());
        assert!(psnr(Method::AllGuides).is_finite());
        assert_eq!(psnr(saved()), psnr(Method::AllGuides), "{}", v.view);
        assert_ne!(psnr(saved()), psnr(Method::Noisy), "{}", v.view);
        // OIDN's inputs (no guide, AO, depth or variance) are another input, with its own result.
        assert!(psnr(Method::AlbedoNormal).is_finite());
        assert_ne!(psnr(Method::AlbedoNormal), psnr(Method::AllGuides), "{}", v.view);
    }
}
