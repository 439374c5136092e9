//! Averaging the weights of several trained models of one network: a uniform "model soup"
//! (Wortsman et al., 2022). Fine-tuning runs that start from the same model and differ in their
//! batches stay in one basin of the loss, where the mean of their weights tends to generalise
//! better than each of them; the averaged model costs no more to run than one of them.

use std::path::{Path, PathBuf};

use burn::module::{Module, ModuleMapper, ModuleVisitor, Param};
use burn::store::ModuleRecord;
use burn::tensor::{Device, Tensor, TensorData};
use rtd_denoise::{DenoiserConfig, DenoiserNet};

use crate::train::save_record;
use crate::TrainError;

/// Collects every float parameter's values, in the module's visiting order.
struct ParamValues(Vec<Vec<f32>>);

impl ModuleVisitor for ParamValues {
    fn visit_float<const D: usize>(&mut self, param: &Param<Tensor<D>>) {
        // A parameter that cannot be read back as f32 is recorded empty; the caller's length
        // check then refuses the average instead of shifting every later parameter.
        self.0.push(param.val().into_data().try_into_vec::<f32>().unwrap_or_default());
    }
}

/// Replaces every float parameter, in visiting order, by the next of `values` (same length).
struct ReplaceParams(std::vec::IntoIter<Vec<f32>>);

impl ModuleMapper for ReplaceParams {
    fn map_float<const D: usize>(&mut self, param: Param<Tensor<D>>) -> Param<Tensor<D>> {
        match self.0.next() {
            Some(values) => param.map(|t| {
                let dims = t.dims();
                Tensor::from_data(TensorData::new(values, dims), &t.device())
            }),
            None => param,
        }
    }
}

fn param_values(net: &DenoiserNet) -> Vec<Vec<f32>> {
    let mut v = ParamValues(vec![]);
    net.visit(&mut v);
    v.0
}

/// The parameter-wise mean of `nets` (all built from one config), or `None` if there are none
/// or their parameters do not line up.
pub fn average_nets(nets: &[DenoiserNet]) -> Option<DenoiserNet> {
    let first = nets.first()?;
    let all: Vec<Vec<Vec<f32>>> = nets.iter().map(param_values).collect();
    let layout: Vec<usize> = all[0].iter().map(Vec::len).collect();
    if all.iter().any(|p| p.iter().map(Vec::len).ne(layout.iter().copied())) {
        return None;
    }
    // Mean of each weight over the models, summed in f64 so the order of models does not matter
    // to the last bit for a handful of them.
    let n = nets.len() as f64;
    let mean: Vec<Vec<f32>> = layout
        .iter()
        .enumerate()
        .map(|(p, &len)| (0..len).map(|i| (all.iter().map(|m| m[p][i] as f64).sum::<f64>() / n) as f32).collect())
        .collect();
    Some(first.clone().map(&mut ReplaceParams(mean.into_iter())))
}

/// Loads the model at `path` (burnpack weights, its config as `path` with extension `.json`).
pub fn load_model(path: &Path, device: &Device) -> Result<(DenoiserConfig, DenoiserNet), TrainError> {
    let cfg_path = path.with_extension("json");
    let text = std::fs::read_to_string(&cfg_path).map_err(|e| TrainError::io(&cfg_path, e))?;
    let config: DenoiserConfig =
        serde_json::from_str(&text).map_err(|e| TrainError::msg(&cfg_path, format!("not a model config: {e}")))?;
    let record = ModuleRecord::load(path).map_err(|e| TrainError::msg(path, e.to_string()))?;
    let net = config
        .init(device)
        .try_load_record(record)
        .map_err(|e| TrainError::msg(path, format!("weights do not match its config: {e}")))?;
    Ok((config, net))
}

/// Averages the models at `inputs` (at least two, all with the same config) into `output`
/// (`.bpk` weights, config as `.json` beside them, each written atomically); returns the config.
pub fn average_models(inputs: &[PathBuf], output: &Path) -> Result<DenoiserConfig, TrainError> {
    if inputs.len() < 2 {
        return Err(TrainError::msg(output, "averaging needs at least two models"));
    }
    if output.extension().and_then(|e| e.to_str()) != Some("bpk") {
        return Err(TrainError::msg(output, "the averaged model's file name must end in .bpk"));
    }
    let device = Device::flex();
    let (config, first) = load_model(&inputs[0], &device)?;
    let mut nets = vec![first];
    for path in &inputs[1..] {
        let (c, net) = load_model(path, &device)?;
        if c != config {
            return Err(TrainError::msg(
                path,
                format!("describes another network than {} (configs differ)", inputs[0].display()),
            ));
        }
        nets.push(net);
    }
    let mean = average_nets(&nets).ok_or_else(|| TrainError::msg(&inputs[0], "parameters do not line up"))?;
    let bytes = mean.into_record().into_bytes().map_err(|e| TrainError::msg(output, e.to_string()))?;
    let cfg = serde_json::to_vec_pretty(&config).map_err(|e| TrainError::msg(output, e.to_string()))?;
    save_record(&output.with_extension("json"), &cfg)?;
    save_record(output, &bytes)?;
    Ok(config)
}

#[cfg(test)]
mod tests {
    use super::*;
    use rtd_denoise::INPUT_CHANNELS;

    fn small_net(seed: u64) -> (DenoiserConfig, DenoiserNet) {
        let device = Device::flex();
        device.seed(seed);
        let config = DenoiserConfig::new(vec![8, 12]).with_bottleneck_blocks(1);
        let net = config.init(&device);
        (config, net)
    }

    fn run(net: &DenoiserNet) -> Vec<f32> {
        let (h, w) = (8, 12);
        let len = INPUT_CHANNELS * h * w;
        let v: Vec<f32> = (0..len).map(|i| ((i * 7919 + 13) % 1000) as f32 / 250.0 - 1.0).collect();
        let x = Tensor::<4>::from_data(TensorData::new(v, [1, INPUT_CHANNELS, h, w]), &Device::flex());
        net.forward(x).into_data().try_to_vec().unwrap()
    }

    /// Each averaged weight is the mean of the inputs' (to f32 rounding), for every parameter.
    #[test]
    fn the_average_is_the_parameter_wise_mean() {
        let nets: Vec<DenoiserNet> = (1..=3).map(|s| small_net(s).1).collect();
        let mean = average_nets(&nets).unwrap();
        let (got, inputs): (Vec<Vec<f32>>, Vec<Vec<Vec<f32>>>) =
            (param_values(&mean), nets.iter().map(param_values).collect());
        assert!(got.len() > 10, "only {} parameters visited", got.len());
        assert_eq!(got.len(), inputs[0].len());
        let mut moved = 0;
        for (p, values) in got.iter().enumerate() {
            for (i, v) in values.iter().enumerate() {
                let want = inputs.iter().map(|m| m[p][i]).sum::<f32>() / 3.0;
                assert!((v - want).abs() <= 1e-6 * (1.0 + want.abs()), "param {p}[{i}]: {v} vs {want}");
                moved += usize::from(*v != inputs[0][p][i]);
            }
        }
        assert!(moved > 100, "the average equals the first model at nearly every weight ({moved} moved)");
        // Averaging a model with itself returns that model's function, bit for bit.
        let twice = average_nets(&[nets[0].clone(), nets[0].clone()]).unwrap();
        assert_eq!(run(&twice), run(&nets[0]));
        assert_ne!(run(&mean), run(&nets[0]));
        assert!(average_nets(&[]).is_none());
    }

    /// Networks of different shapes are refused, not averaged over a shifted layout.
    #[test]
    fn nets_of_different_shapes_are_refused() {
        let (_, a) = small_net(1);
        let device = Device::flex();
        let b = DenoiserConfig::new(vec![8, 16]).with_bottleneck_blocks(1).init(&device);
        assert!(average_nets(&[a, b]).is_none());
    }

    /// Files: the average is written as weights + config that load back to the averaged net;
    /// a model of another config and a lone model are refused, naming the file, writing nothing.
    #[test]
    fn average_models_writes_a_loadable_model_and_refuses_mismatches() {
        let dir = std::env::temp_dir().join(format!("rtd-average-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let save = |name: &str, config: &DenoiserConfig, net: &DenoiserNet| {
            let path = dir.join(name);
            std::fs::write(&path, &*net.clone().into_record().into_bytes().unwrap()).unwrap();
            std::fs::write(path.with_extension("json"), serde_json::to_vec(config).unwrap()).unwrap();
            path
        };
        let (config, a) = small_net(4);
        let (_, b) = small_net(5);
        let (pa, pb) = (save("a.bpk", &config, &a), save("b.bpk", &config, &b));
        let out = dir.join("soup.bpk");
        assert_eq!(average_models(&[pa.clone(), pb.clone()], &out).unwrap(), config);
        let (loaded_config, loaded) = load_model(&out, &Device::flex()).unwrap();
        assert_eq!(loaded_config, config);
        assert_eq!(run(&loaded), run(&average_nets(&[a.clone(), b]).unwrap()));

        let other = DenoiserConfig::new(vec![8, 16]).with_bottleneck_blocks(1);
        let pc = save("c.bpk", &other, &other.init(&Device::flex()));
        let bad = dir.join("bad.bpk");
        let err = average_models(&[pa.clone(), pc.clone()], &bad).unwrap_err().to_string();
        assert!(err.starts_with(&pc.display().to_string()) && err.contains("configs differ"), "{err}");
        let err = average_models(std::slice::from_ref(&pa), &bad).unwrap_err().to_string();
        assert!(err.contains("at least two"), "{err}");
        assert!(!bad.exists() && !bad.with_extension("json").exists());
        std::fs::remove_dir_all(&dir).ok();
    }
}
