//! Mutation fuzzing of every loader that reads a stranger's bytes, on the stable toolchain: an
//! in-process harness whose mutations are drawn through `arbitrary` from a seeded generator,
//! starting from small valid files it writes itself. A crash is a panic, a run over 10 s of
//! processor time on one input, or an allocation that would take the process past 2 GiB (refused by the
//! allocator below, which aborts the run). Found crashes are kept in
//! `tests/fuzz-regressions/TARGET/` and replayed first, every run.
//!
//! `RTD_FUZZ_SECS` sets the seconds per target (default 30, as CI runs it); `RTD_FUZZ_CPU_SECS`
//! instead bounds each target by the processor time the process spends on it, so a campaign
//! run at low priority beside other work still fuzzes each target for the stated time;
//! `RTD_FUZZ_SEED` the generator's seed; `RTD_FUZZ_TARGETS` a comma-separated subset. Each
//! target prints its executions, wall and processor seconds; RELIABILITY.md records the long
//! campaigns.

use std::alloc::{GlobalAlloc, Layout, System};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicUsize, Ordering};
use std::time::{Duration, Instant};

use arbitrary::Unstructured;
use base64::Engine;

/// The memory bound of a fuzz run: allocations past it fail (and the run aborts).
const MEMORY_LIMIT: usize = 2 << 30;
/// The longest one input may take.
const TIME_LIMIT: Duration = Duration::from_secs(10);

/// The system allocator, refusing what would take the live total past [`MEMORY_LIMIT`].
struct Bounded;

static LIVE: AtomicUsize = AtomicUsize::new(0);

unsafe impl GlobalAlloc for Bounded {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        if LIVE.fetch_add(layout.size(), Ordering::Relaxed) + layout.size() > MEMORY_LIMIT {
            LIVE.fetch_sub(layout.size(), Ordering::Relaxed);
            return std::ptr::null_mut();
        }
        unsafe { System.alloc(layout) }
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        LIVE.fetch_sub(layout.size(), Ordering::Relaxed);
        unsafe { System.dealloc(ptr, layout) }
    }
}

#[global_allocator]
static ALLOCATOR: Bounded = Bounded;

/// One loader under test: its name, the file name its input is written to, and the call.
struct Target {
    name: &'static str,
    file: &'static str,
    load: fn(&Path, &[u8]),
}

fn targets() -> Vec<Target> {
    vec![
        Target { name: "gltf", file: "scene.gltf", load: |p, _| drop(rtd::scene::load_scene(p)) },
        Target { name: "glb", file: "scene.glb", load: |p, _| drop(rtd::scene::load_scene(p)) },
        Target { name: "obj", file: "scene.obj", load: |p, _| drop(rtd::scene::load_scene(p)) },
        Target {
            name: "mtl",
            file: "scene.mtl",
            load: |p, _| drop(rtd::scene::load_scene(&p.with_file_name("uses-mtl.obj"))),
        },
        Target { name: "exr", file: "image.exr", load: |p, _| drop(rtd::image::read_exr(p)) },
        Target { name: "png", file: "image.png", load: |p, _| drop(rtd::image::read_ldr(p)) },
        Target { name: "jpeg", file: "image.jpg", load: |p, _| drop(rtd::image::read_ldr(p)) },
        Target { name: "pfm", file: "image.pfm", load: |p, _| drop(rtd::image::read_pfm(p)) },
        Target { name: "hdr", file: "sky.hdr", load: |p, _| drop(rtd::image::read_rgbe(p)) },
        Target {
            name: "model",
            file: "model.bpk",
            load: |_, bytes| drop(rtd::denoise::Denoiser::from_bytes(MODEL_JSON, bytes.to_vec(), "fuzz")),
        },
        Target {
            name: "upload",
            file: "upload.bin",
            load: |p, bytes| {
                // What the service does with an upload's bytes before queuing it.
                let _ = rtd::image::read_image_header(p, bytes);
                let _ = rtd::service::check_scene(bytes);
            },
        },
    ]
}

const MODEL_JSON: &str = include_str!("../models/rtd-denoiser.json");

/// Small valid inputs for `target`, written by the harness (and any kept regressions).
fn corpus(target: &str, dir: &Path) -> Vec<Vec<u8>> {
    let repo = Path::new(env!("CARGO_MANIFEST_DIR"));
    let cornell = std::fs::read_to_string(repo.join("scenes/cornell-box.gltf")).unwrap();
    let mut seeds = match target {
        "gltf" => vec![cornell.clone().into_bytes(), textured_gltf(&cornell, dir), nested_gltf(&cornell)],
        "glb" => vec![glb(&cornell)],
        "obj" => vec![OBJ.as_bytes().to_vec()],
        "mtl" => vec![MTL.as_bytes().to_vec()],
        "exr" => vec![exr(dir, &["R", "G", "B"]), exr(dir, &["R", "G", "B", "albedo.R", "albedo.G", "albedo.B"])],
        "png" => vec![ldr(image::ImageFormat::Png), tiny_png()],
        "jpeg" => vec![ldr(image::ImageFormat::Jpeg)],
        "hdr" => vec![rgbe(9, 4), rgbe(40, 3)],
        "pfm" => vec![pfm(false), pfm(true), b"Pf 2 1 1.0\n\0\0\0\0\0\0\0\0".to_vec()],
        "model" => vec![std::fs::read(repo.join("models/rtd-denoiser.bpk")).unwrap()],
        "upload" => {
            vec![tiny_png(), ldr(image::ImageFormat::Jpeg), exr(dir, &["R", "G", "B"]), glb(&cornell), pfm(true)]
        }
        _ => unreachable!(),
    };
    let kept = repo.join("tests/fuzz-regressions").join(target);
    if let Ok(entries) = std::fs::read_dir(kept) {
        seeds.extend(entries.flatten().map(|e| std::fs::read(e.path()).unwrap()));
    }
    seeds
}

const OBJ: &str = "mtllib scene.mtl\no box\nv 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nvt 0 0\nvt 1 0\nvt 1 1\nvn 0 0 1\n\
usemtl red\nf 1/1/1 2/2/1 3/3/1\nf 1/1/1 3/3/1 4/1/1\n";
const MTL: &str = "newmtl red\nKd 0.8 0.1 0.1\nKs 0.04 0.04 0.04\nNs 20\nKe 0 0 0\nd 1\nNi 1.5\nillum 2\n";

/// A Radiance `.hdr` of a gradient (rows of 8 to 0x7fff pixels are run-length encoded).
fn rgbe(w: u32, h: u32) -> Vec<u8> {
    let img = image::Rgb32FImage::from_fn(w, h, |x, y| image::Rgb([x as f32 * 0.3, y as f32 + 0.5, 2.0]));
    let mut out = std::io::Cursor::new(Vec::new());
    image::DynamicImage::ImageRgb32F(img).write_to(&mut out, image::ImageFormat::Hdr).unwrap();
    out.into_inner()
}

/// A 5×3 PFM (or PHM) of a gradient.
fn pfm(half: bool) -> Vec<u8> {
    let px = (0..15).map(|i| glam::Vec3::new(i as f32, 0.5, -1.0)).collect();
    rtd::image::encode_pfm(&rtd::image::HdrImage::from_pixels(5, 3, px), half)
}

fn tiny_png() -> Vec<u8> {
    let img = image::RgbImage::from_fn(2, 2, |x, y| image::Rgb([(x * 200) as u8, (y * 200) as u8, 90]));
    let mut out = std::io::Cursor::new(Vec::new());
    img.write_to(&mut out, image::ImageFormat::Png).unwrap();
    out.into_inner()
}

fn ldr(format: image::ImageFormat) -> Vec<u8> {
    let img = image::RgbImage::from_fn(16, 12, |x, y| image::Rgb([(x * 15) as u8, (y * 20) as u8, 128]));
    let mut out = std::io::Cursor::new(Vec::new());
    img.write_to(&mut out, format).unwrap();
    out.into_inner()
}

fn exr(dir: &Path, channels: &[&str]) -> Vec<u8> {
    let mut layers = rtd::image::Layers::new(8, 4);
    for (i, c) in channels.iter().enumerate() {
        layers.push(*c, (0..32).map(|k| (k * (i + 1)) as f32 / 32.0).collect());
    }
    rtd::image::encode_exr(&dir.join("seed.exr"), &layers).unwrap()
}

/// The Cornell box with a 2×2 PNG texture embedded as a data URI on its first material.
fn textured_gltf(cornell: &str, _dir: &Path) -> Vec<u8> {
    let mut doc: serde_json::Value = serde_json::from_str(cornell).unwrap();
    let png = base64::engine::general_purpose::STANDARD.encode(tiny_png());
    doc["images"] = serde_json::json!([{ "uri": format!("data:image/png;base64,{png}") }]);
    doc["textures"] = serde_json::json!([{ "source": 0 }]);
    doc["materials"][0]["pbrMetallicRoughness"]["baseColorTexture"] = serde_json::json!({ "index": 0 });
    serde_json::to_vec(&doc).unwrap()
}

/// The Cornell box as a node hierarchy: its nodes under a transformed root with a camera and
/// a punctual light, and a second scene, so that mutations reach the node walk (`children`,
/// transforms, camera and light references) and the scene choice.
fn nested_gltf(cornell: &str) -> Vec<u8> {
    let mut doc: serde_json::Value = serde_json::from_str(cornell).unwrap();
    let roots = doc["scenes"][0]["nodes"].clone();
    let nodes = doc["nodes"].as_array_mut().unwrap();
    let root = nodes.len();
    nodes.push(
        serde_json::json!({"name": "root", "children": roots, "rotation": [0, 0.38, 0, 0.92], "scale": [1, 2, 1]}),
    );
    nodes.push(serde_json::json!({"camera": 0, "translation": [0, 1, 4], "children": [root + 2]}));
    nodes.push(serde_json::json!({"extensions": {"KHR_lights_punctual": {"light": 0}}, "translation": [0, 1.5, 0]}));
    doc["scenes"] = serde_json::json!([{"nodes": [root, root + 1]}, {"name": "empty", "nodes": []}]);
    doc["scene"] = serde_json::json!(0);
    doc["cameras"] =
        serde_json::json!([{"type": "perspective", "perspective": {"yfov": 0.7, "znear": 0.1, "aspectRatio": 1.5}}]);
    doc["extensions"] = serde_json::json!({"KHR_lights_punctual": {"lights": [
        {"type": "spot", "intensity": 40, "color": [1, 0.9, 0.8], "spot": {"innerConeAngle": 0.2, "outerConeAngle": 0.5}}
    ]}});
    doc["extensionsUsed"].as_array_mut().unwrap().push(serde_json::json!("KHR_lights_punctual"));
    serde_json::to_vec(&doc).unwrap()
}

/// The Cornell box as a binary .glb: its data-URI buffer moved into the BIN chunk.
fn glb(cornell: &str) -> Vec<u8> {
    let mut doc: serde_json::Value = serde_json::from_str(cornell).unwrap();
    let uri = doc["buffers"][0]["uri"].as_str().unwrap().to_string();
    let mut bin = base64::engine::general_purpose::STANDARD.decode(uri.split_once(',').unwrap().1).unwrap();
    doc["buffers"][0].as_object_mut().unwrap().remove("uri");
    let mut js = serde_json::to_vec(&doc).unwrap();
    while !js.len().is_multiple_of(4) {
        js.push(b' ');
    }
    while !bin.len().is_multiple_of(4) {
        bin.push(0);
    }
    let mut out = b"glTF".to_vec();
    out.extend(2u32.to_le_bytes());
    out.extend(((28 + js.len() + bin.len()) as u32).to_le_bytes());
    out.extend((js.len() as u32).to_le_bytes());
    out.extend(b"JSON");
    out.extend(&js);
    out.extend((bin.len() as u32).to_le_bytes());
    out.extend(b"BIN\0");
    out.extend(&bin);
    out
}

/// A fixed-seed xorshift: the bytes `arbitrary` draws each mutation from.
struct Entropy(u64);

impl Entropy {
    fn bytes(&mut self, n: usize) -> Vec<u8> {
        (0..n)
            .map(|_| {
                self.0 ^= self.0 << 13;
                self.0 ^= self.0 >> 7;
                self.0 ^= self.0 << 17;
                (self.0 >> 24) as u8
            })
            .collect()
    }
}

/// Values that break parsers: boundaries of integer widths, float specials, huge counts.
const INTERESTING: &[&[u8]] = &[
    b"0",
    b"-1",
    b"1e38",
    b"-1e38",
    b"NaN",
    b"inf",
    b"4294967295",
    b"2147483648",
    b"65536",
    b"1e400",
    b"\"\"",
    b"null",
    b"[]",
    b"{}",
    b"\xff\xff\xff\xff",
    b"\x00\x00\x00\x00",
    b"\x7f\xff\xff\xff",
    b"\x00\x00\x80\x7f",
];

/// One input: a corpus entry with 1–8 mutations drawn from `u`.
fn mutate(seeds: &[Vec<u8>], u: &mut Unstructured) -> arbitrary::Result<Vec<u8>> {
    let mut data = u.choose(seeds)?.clone();
    for _ in 0..u.int_in_range(1..=8u8)? {
        let len = data.len().max(1);
        let at = u.int_in_range(0..=len - 1)?;
        match u.int_in_range(0..=7u8)? {
            0 if !data.is_empty() => data[at] ^= 1 << u.int_in_range(0..=7u8)?,
            1 if !data.is_empty() => data[at] = u.arbitrary()?,
            2 => {
                let v = *u.choose(INTERESTING)?;
                let end = (at + v.len()).min(data.len());
                data.splice(at.min(data.len())..end, v.iter().copied());
            }
            3 => {
                let n = u.int_in_range(1..=16usize)?;
                let bytes: Vec<u8> = (0..n).map(|_| u.arbitrary()).collect::<arbitrary::Result<_>>()?;
                data.splice(at.min(data.len())..at.min(data.len()), bytes);
            }
            4 => {
                let end = (at + u.int_in_range(1..=64usize)?).min(data.len());
                data.drain(at.min(end)..end);
            }
            5 => data.truncate(at),
            6 => {
                // Duplicate a span elsewhere (repeats chunks, counts, tags).
                let end = (at + u.int_in_range(1..=64usize)?).min(data.len());
                let span = data[at.min(end)..end].to_vec();
                let to = u.int_in_range(0..=data.len())?;
                data.splice(to..to, span);
            }
            _ => {
                // Splice in a span of another seed.
                let other = u.choose(seeds)?;
                let from = u.int_in_range(0..=other.len().saturating_sub(1))?;
                let end = (from + u.int_in_range(1..=256usize)?).min(other.len());
                let to = at.min(data.len());
                data.splice(to..to, other[from..end].iter().copied());
            }
        }
    }
    Ok(data)
}

/// What one target found: executions, the crashing inputs (kept under `target/`), and the
/// dependency panics that rtd's fence turned into errors.
struct Campaign {
    runs: u64,
    crashes: Vec<(PathBuf, String)>,
    contained: u64,
    /// Wall-clock seconds spent.
    wall: f64,
    /// Processor seconds (user + system) the process spent.
    cpu: f64,
}

/// How long a target runs: wall-clock seconds, or processor seconds of this process.
#[derive(Clone, Copy)]
enum Budget {
    Wall(f64),
    Cpu(f64),
}

/// Processor time (user + system, all threads) this process has used so far.
fn process_cpu() -> Duration {
    let mut t = libc::timespec { tv_sec: 0, tv_nsec: 0 };
    // SAFETY: clock_gettime writes the timespec it is given and nothing else.
    unsafe { libc::clock_gettime(libc::CLOCK_PROCESS_CPUTIME_ID, &mut t) };
    Duration::new(t.tv_sec as u64, t.tv_nsec as u32)
}

/// [`process_cpu`] in seconds.
fn process_cpu_seconds() -> f64 {
    process_cpu().as_secs_f64()
}

/// The wall-clock bound on one input, for a hang that uses no processor time (a blocked call):
/// long, since a campaign run at low priority beside other work may wait its turn for minutes.
const WALL_LIMIT: Duration = Duration::from_secs(600);

/// Aborts the run when one input has used more than [`TIME_LIMIT`] of processor time, or
/// [`WALL_LIMIT`] of wall time (a hang would otherwise stall CI); the input stays in the work
/// folder. `busy` holds the number of the input in flight (from 1), 0 between inputs. Processor
/// time, not wall time, is the measure: at low priority a loader can wait far longer than it
/// runs, and waiting is no crash.
fn watchdog(busy: &'static AtomicUsize, input: PathBuf) {
    std::thread::spawn(move || {
        // The input last seen in flight, with the processor and wall time when first seen.
        let mut seen: Option<(usize, Duration, Instant)> = None;
        loop {
            std::thread::sleep(Duration::from_millis(500));
            let now = busy.load(Ordering::Relaxed);
            match seen {
                Some((n, cpu, wall)) if n == now && now != 0 => {
                    if process_cpu() - cpu > TIME_LIMIT || wall.elapsed() > WALL_LIMIT {
                        eprintln!("fuzz: one input ran past {TIME_LIMIT:?} of processor time: {}", input.display());
                        std::process::abort();
                    }
                }
                _ => seen = (now != 0).then(|| (now, process_cpu(), Instant::now())),
            }
        }
    });
}

fn fuzz(target: &Target, budget: Budget, seed: u64) -> Campaign {
    // A fixed folder, so that the input in flight is still there if the run aborts.
    let work = Path::new(env!("CARGO_TARGET_TMPDIR")).join("fuzz-work").join(target.name);
    std::fs::create_dir_all(&work).unwrap();
    std::fs::write(work.join("uses-mtl.obj"), OBJ).unwrap();
    std::fs::write(work.join("scene.mtl"), MTL).unwrap();
    let seeds = corpus(target.name, &work);
    let path = work.join(target.file);
    let out = Path::new(env!("CARGO_TARGET_TMPDIR")).join("fuzz-crashes").join(target.name);
    let mut entropy = Entropy((seed ^ (target.name.len() as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15)) | 1);
    let mut campaign = Campaign { runs: 0, crashes: vec![], contained: 0, wall: 0.0, cpu: 0.0 };
    let contained_before = rtd::image::contained_panics();
    let busy: &'static AtomicUsize = Box::leak(Box::new(AtomicUsize::new(0)));
    watchdog(busy, path.clone());
    let (start, cpu_start) = (Instant::now(), process_cpu_seconds());
    let spent = || match budget {
        Budget::Wall(_) => start.elapsed().as_secs_f64(),
        Budget::Cpu(_) => process_cpu_seconds() - cpu_start,
    };
    let limit = match budget {
        Budget::Wall(s) | Budget::Cpu(s) => s,
    };
    // The seeds themselves first (and so every kept regression), then mutations.
    let mut queue: Vec<Vec<u8>> = seeds.clone();
    while !queue.is_empty() || spent() < limit {
        let input = match queue.pop() {
            Some(i) => i,
            None => {
                let raw = entropy.bytes(256);
                match mutate(&seeds, &mut Unstructured::new(&raw)) {
                    Ok(i) => i,
                    Err(_) => continue,
                }
            }
        };
        std::fs::write(&path, &input).unwrap();
        let t = process_cpu();
        busy.store(campaign.runs as usize + 1, Ordering::Relaxed);
        let result = std::panic::catch_unwind(|| (target.load)(&path, &input));
        busy.store(0, Ordering::Relaxed);
        let took = process_cpu() - t;
        campaign.runs += 1;
        let why = match result {
            Err(panic) => Some(
                panic
                    .downcast_ref::<String>()
                    .cloned()
                    .or_else(|| panic.downcast_ref::<&str>().map(|s| s.to_string()))
                    .unwrap_or_else(|| "panic".into()),
            ),
            Ok(()) if took > TIME_LIMIT => Some(format!("took {took:?} of processor time")),
            Ok(()) => None,
        };
        if let Some(why) = why {
            std::fs::create_dir_all(&out).unwrap();
            let kept = out.join(format!("crash-{}", campaign.crashes.len()));
            std::fs::write(&kept, &input).unwrap();
            campaign.crashes.push((kept, why));
        }
    }
    campaign.contained = rtd::image::contained_panics() - contained_before;
    (campaign.wall, campaign.cpu) = (start.elapsed().as_secs_f64(), process_cpu_seconds() - cpu_start);
    campaign
}

/// The glTF seeds are valid scenes (a mutation of a file refused outright reaches little), and
/// the nested one reaches the node walk's camera (the box has one of its own) and light.
#[test]
fn the_gltf_seeds_load() {
    let dir = tempfile::tempdir().unwrap();
    for (i, seed) in corpus("gltf", dir.path()).iter().take(3).enumerate() {
        let path = dir.path().join(format!("seed{i}.gltf"));
        std::fs::write(&path, seed).unwrap();
        let scene = rtd::scene::load_scene(&path).unwrap_or_else(|e| panic!("seed {i}: {e}"));
        assert!(!scene.triangles.is_empty());
        if i == 2 {
            assert_eq!((scene.cameras.len(), scene.lights.len()), (2, 1), "{:?}", scene.warnings);
        }
    }
}

#[test]
fn loaders_survive_mutated_input() {
    let env = |name: &str| std::env::var(name).ok().and_then(|s| s.parse::<f64>().ok());
    let budget = match (env("RTD_FUZZ_CPU_SECS"), env("RTD_FUZZ_SECS")) {
        (Some(cpu), _) => Budget::Cpu(cpu),
        (None, wall) => Budget::Wall(wall.unwrap_or(30.0)),
    };
    let seed: u64 = std::env::var("RTD_FUZZ_SEED").ok().and_then(|s| s.parse().ok()).unwrap_or(1);
    let only = std::env::var("RTD_FUZZ_TARGETS").ok();
    let mut failures = Vec::new();
    for target in targets() {
        if only.as_ref().is_some_and(|o| !o.split(',').any(|t| t == target.name)) {
            continue;
        }
        let c = fuzz(&target, budget, seed);
        eprintln!(
            "fuzz {:>6}: {:>8} runs in {:.1} s ({:.1} s of processor time), {} crashes, {} dependency panics contained",
            target.name,
            c.runs,
            c.wall,
            c.cpu,
            c.crashes.len(),
            c.contained
        );
        for (input, why) in c.crashes.iter().take(5) {
            failures.push(format!("{}: {} ({why})", target.name, input.display()));
        }
    }
    assert!(failures.is_empty(), "crashes:\n{}", failures.join("\n"));
}

/// `RTD_FUZZ_REPLAY=TARGET:FILE` runs one input through its loader without catching a panic,
/// for its backtrace; without it this test does nothing.
#[test]
fn replay_one_input() {
    let Ok(spec) = std::env::var("RTD_FUZZ_REPLAY") else { return };
    let (name, file) = spec.split_once(':').expect("TARGET:FILE");
    let target = targets().into_iter().find(|t| t.name == name).expect("a target name");
    let work = tempfile::tempdir().unwrap();
    std::fs::write(work.path().join("uses-mtl.obj"), OBJ).unwrap();
    let path = work.path().join(target.file);
    let bytes = std::fs::read(file).unwrap();
    std::fs::write(&path, &bytes).unwrap();
    (target.load)(&path, &bytes);
}

/// Every kept crash, through the command line: a one-line error naming the file, exit 1, and
/// no panic message.
#[test]
fn kept_crashes_give_a_one_line_error_through_the_cli() {
    let repo = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/fuzz-regressions");
    let work = tempfile::tempdir().unwrap();
    let (mut seen, mut refused) = (0, 0);
    let cornell_path = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/cornell-box.gltf");
    let cornell = cornell_path.to_str().unwrap();
    let through_cli = [
        ("gltf", "s.gltf"),
        ("glb", "s.glb"),
        ("obj", "s.obj"),
        ("mtl", "scene.mtl"),
        ("exr", "c.exr"),
        ("jpeg", "c.jpg"),
        ("png", "c.png"),
        ("pfm", "c.pfm"),
        ("hdr", "sky.hdr"),
    ];
    // Model files and uploads have no one-file CLI path here (a model needs its images; an
    // upload goes to the service, whose tests replay refusals): they are replayed in process by
    // `loaders_survive_mutated_input`. Any other target's folder must be listed above.
    for entry in std::fs::read_dir(&repo).unwrap().flatten() {
        let name = entry.file_name().to_string_lossy().to_string();
        let known = through_cli.iter().any(|(t, _)| *t == name) || ["model", "upload"].contains(&name.as_str());
        assert!(known, "tests/fuzz-regressions/{name} is not replayed through the CLI");
    }
    for (target, file) in through_cli {
        let Ok(entries) = std::fs::read_dir(repo.join(target)) else { continue };
        for entry in entries.flatten() {
            let input = work.path().join(file);
            std::fs::copy(entry.path(), &input).unwrap();
            std::fs::write(work.path().join("uses-mtl.obj"), OBJ).unwrap();
            let out = work.path().join("out.exr");
            let (o, named) = (out.to_str().unwrap(), input.to_str().unwrap());
            let args: Vec<&str> = match target {
                "exr" | "jpeg" | "png" | "pfm" => vec!["denoise", "--color", named, "--guide", named, "-o", o],
                "hdr" => {
                    vec!["render", cornell, "--env", named, "--spp", "1", "--width", "8", "--height", "8", "-o", o]
                }
                "mtl" => vec!["guide", work.path().join("uses-mtl.obj").to_str().unwrap().to_owned().leak(), "-o", o],
                _ => vec!["guide", named, "-o", o],
            };
            let run = std::process::Command::new(env!("CARGO_BIN_EXE_rtd")).args(&args).output().unwrap();
            let err = String::from_utf8_lossy(&run.stderr);
            let what = format!("{target} {}", entry.path().display());
            assert!(!err.contains("panicked"), "{what}: {err}");
            seen += 1;
            if target == "mtl" || run.status.success() {
                // A bad material library is a warning (the scene still loads), and an image
                // whose header and data agree despite the mutation is simply an image.
                continue;
            }
            assert_eq!(run.status.code(), Some(1), "{what}: {err}");
            assert_eq!(err.trim_end().lines().count(), 1, "{what}: {err}");
            assert!(err.contains(&*input.to_string_lossy()), "{what}: {err}");
            refused += 1;
        }
    }
    assert!(seen >= 16, "only {seen} kept crashes were replayed");
    // The glTF, GLB, OBJ and EXR ones are malformed beyond use: each must be refused.
    assert!(refused >= 9, "only {refused} kept crashes were refused");
}
