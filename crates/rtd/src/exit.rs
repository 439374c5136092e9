//! How a command ends, as the process's exit status: 0 when it finished, 1 on an error, 2 on a
//! usage error (bad or missing arguments), and 130 (128 + SIGINT, the shell convention) when
//! Ctrl-C stopped it after it kept its finished work (a render's finished passes, a dataset's
//! finished views, a training run's checkpoint).

/// Exit status of a finished command.
pub const EXIT_OK: i32 = 0;
/// Exit status of a failed command.
pub const EXIT_ERROR: i32 = 1;
/// Exit status of a command line that could not be parsed.
pub const EXIT_USAGE: i32 = 2;
/// Exit status of a command interrupted by Ctrl-C after keeping its finished work.
pub const EXIT_INTERRUPTED: i32 = 130;

/// A command line clap refused; its message is one line.
#[derive(Debug, thiserror::Error)]
#[error("{0}")]
pub struct UsageError(pub String);

/// A command stopped by Ctrl-C after keeping its finished work; the message says what was kept
/// and how to go on.
#[derive(Debug, thiserror::Error)]
#[error("{0}")]
pub struct Interrupted(pub String);

/// The exit status and the line to print on standard error for the outcome of [`crate::run`].
pub fn outcome(result: &anyhow::Result<()>) -> (i32, Option<String>) {
    match result {
        Ok(()) => (EXIT_OK, None),
        Err(e) if e.downcast_ref::<Interrupted>().is_some() => {
            (EXIT_INTERRUPTED, Some(format!("rtd: interrupted: {}", crate::one_line(e))))
        }
        Err(e) => {
            let status = if e.downcast_ref::<UsageError>().is_some() { EXIT_USAGE } else { EXIT_ERROR };
            (status, Some(format!("rtd: error: {}", crate::one_line(e))))
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn each_outcome_has_its_status_and_line() {
        assert_eq!(outcome(&Ok(())), (0, None));
        let usage = outcome(&Err(UsageError("unexpected argument '--x'".into()).into()));
        assert_eq!(usage, (2, Some("rtd: error: unexpected argument '--x'".into())));
        let stopped = outcome(&Err(Interrupted("8 passes kept".into()).into()));
        assert_eq!(stopped, (130, Some("rtd: interrupted: 8 passes kept".into())));
        assert_eq!(outcome(&Err(anyhow::anyhow!("x.gltf: no such file"))).0, 1);
    }
}
