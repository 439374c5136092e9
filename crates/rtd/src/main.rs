//! The `rtd` binary: parse arguments, run, print any error on one line, and exit with the
//! status [`rtd::exit`] gives (0, 1 on errors, 2 on usage errors, 130 when interrupted).

fn main() {
    let (status, line) = rtd::exit::outcome(&rtd::run(std::env::args_os()));
    if let Some(line) = line {
        eprintln!("{line}");
    }
    std::process::exit(status);
}
