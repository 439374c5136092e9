//! The `rtd` binary: parse arguments, run, and print any error on one line.

fn main() {
    if let Err(e) = rtd::run(std::env::args_os()) {
        eprintln!("rtd: error: {}", rtd::one_line(&e));
        std::process::exit(1);
    }
}
