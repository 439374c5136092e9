//! The `rtd` command line: a thin layer over the library crates.
//!
//! Everything a command does is a library call ([`render_command::render`] and friends), so
//! tests and benchmarks reach the same code paths as users.

pub mod args;
pub mod bench_command;
pub mod denoise_command;
pub mod guide_command;
pub mod progress;
pub mod render_command;
pub mod train_command;

pub use rtd_bench as bench;
pub use rtd_denoise as denoise;
pub use rtd_guide as guide;
pub use rtd_image as image;
pub use rtd_render as render;
pub use rtd_scene as scene;
pub use rtd_train as train;

use clap::Parser;

/// Runs the command line given by `args` (including the program name).
pub fn run<I, T>(args: I) -> anyhow::Result<()>
where
    I: IntoIterator<Item = T>,
    T: Into<std::ffi::OsString> + Clone,
{
    let cli = match args::Cli::try_parse_from(args) {
        Ok(c) => c,
        Err(e) if matches!(e.kind(), clap::error::ErrorKind::DisplayHelp | clap::error::ErrorKind::DisplayVersion) => {
            print!("{e}");
            return Ok(());
        }
        Err(e) => return Err(anyhow::anyhow!(first_line(&e.to_string()))),
    };
    match cli.command {
        args::Command::Render(a) => render_command::render(&a).map(|_| ()),
        args::Command::Guide(a) => guide_command::guide(&a).map(|_| ()),
        args::Command::Datagen(a) => train_command::datagen(&a).map(|_| ()),
        args::Command::Denoise(a) => denoise_command::denoise(&a).map(|_| ()),
        args::Command::Bench(a) => bench_command::bench(&a),
        args::Command::Train(a) => train_command::train(&a).map(|_| ()),
    }
}

/// An error and its causes on one line.
pub fn one_line(e: &anyhow::Error) -> String {
    let mut parts: Vec<String> = Vec::new();
    for cause in e.chain() {
        let s = cause.to_string().replace('\n', " ");
        if !parts.iter().any(|p| p.contains(&s)) {
            parts.push(s);
        }
    }
    parts.join(": ")
}

/// The first meaningful line of clap's multi-line error text, without its "error: " prefix.
fn first_line(s: &str) -> String {
    let line = s.lines().find(|l| !l.trim().is_empty()).unwrap_or(s);
    line.trim_start_matches("error: ").to_string()
}
