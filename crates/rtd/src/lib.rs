//! The `rtd` command line: a thin layer over the library crates.
//!
//! Everything a command does is a library call ([`render_command::render`] and friends), so
//! tests and benchmarks reach the same code paths as users.

#![warn(missing_docs)]

mod arg_values;
pub mod args;
pub mod bench_command;
pub mod denoise_command;
pub mod exit;
pub mod guide_command;
pub mod heap;
pub mod output;
pub mod progress;
pub mod render_command;
pub mod service_args;
pub mod service_command;
pub mod train_args;
pub mod train_command;

pub use rtd_bench as bench;
pub use rtd_denoise as denoise;
pub use rtd_guide as guide;
pub use rtd_image as image;
pub use rtd_pipeline as pipeline;
pub use rtd_render as render;
pub use rtd_scene as scene;
pub use rtd_service as service;
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
            return print_text(&e.to_string());
        }
        Err(e) => return Err(exit::UsageError(first_paragraph(&e.to_string())).into()),
    };
    match cli.command {
        args::Command::Render(a) => render_command::render(&a).map(|_| ()),
        args::Command::Guide(a) => guide_command::guide(&a).map(|_| ()),
        args::Command::Datagen(a) => train_command::datagen(&a).map(|_| ()),
        args::Command::Denoise(a) => denoise_command::denoise(&a).map(|_| ()),
        args::Command::Bench(a) => bench_command::bench(&a),
        args::Command::Train(a) => train_command::train(&a).map(|_| ()),
        args::Command::Serve(a) => service_command::serve(&a),
        args::Command::Worker(a) => service_command::worker(&a),
    }
}

/// Writes `text` to standard output. A reader that has gone away (`rtd train --help | head`)
/// is not an error, since the command's files are written by then; any other write error is.
pub fn print_text(text: &str) -> anyhow::Result<()> {
    use std::io::Write;
    let mut out = std::io::stdout().lock();
    match out.write_all(text.as_bytes()).and_then(|_| out.flush()) {
        Err(e) if e.kind() == std::io::ErrorKind::BrokenPipe => Ok(()),
        r => r.map_err(|e| anyhow::anyhow!("cannot write to standard output: {e}")),
    }
}

/// [`print_text`] with a newline after it.
pub fn print_line(text: &str) -> anyhow::Result<()> {
    print_text(&format!("{text}\n"))
}

/// An error and its causes on one line, each cause once.
pub fn one_line(e: &anyhow::Error) -> String {
    let mut parts: Vec<String> = Vec::new();
    for cause in e.chain() {
        let s = cause.to_string().replace('\n', " ");
        // A cause already said in other words ("x.gltf: no such file" over the I/O error's "No
        // such file or directory (os error 2)") is left out: compare its opening words.
        let said = parts.join(": ").to_lowercase();
        let opening: String = s.to_lowercase().chars().take(12).collect();
        if !parts.iter().any(|p| p.contains(&s)) && !said.contains(&opening) {
            parts.push(s);
        }
    }
    parts.join(": ")
}

/// Clap's multi-line error text as one line: its first paragraph (the message, and for
/// "the following required arguments were not provided:" the arguments listed under it),
/// without the "error: " prefix, the usage line and the tips after it.
fn first_paragraph(s: &str) -> String {
    let lines = s.lines().skip_while(|l| l.trim().is_empty()).take_while(|l| !l.trim().is_empty());
    let text = lines.map(str::trim).collect::<Vec<_>>().join(" ");
    text.trim_start_matches("error: ").to_string()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_cause_already_said_is_not_repeated() {
        let e = anyhow::Error::from(rtd_scene::load_scene(std::path::Path::new("/nonexistent/x.gltf")).unwrap_err());
        assert_eq!(one_line(&e), "/nonexistent/x.gltf: no such file");
        let e = anyhow::Error::from(rtd_image::read_ldr(std::path::Path::new("/nonexistent/x.png")).unwrap_err());
        assert_eq!(one_line(&e), "/nonexistent/x.png: no such file");
    }

    #[test]
    fn clap_errors_keep_the_arguments_they_list() {
        let e = args::Cli::try_parse_from(["rtd", "train", "-o", "o"]).unwrap_err();
        assert_eq!(
            first_paragraph(&e.to_string()),
            "the following required arguments were not provided: --data <DATA>"
        );
        let e = args::Cli::try_parse_from(["rtd", "render", "--spp", "0"]).unwrap_err();
        let line = first_paragraph(&e.to_string());
        assert!(line.starts_with("invalid value '0' for '--spp") && !line.contains("Usage"), "{line}");
    }
}
