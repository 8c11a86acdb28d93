//! The library's messages in the command line's words: the render job names its options as
//! Python spells them (`` `tilt_shift` ``); here each becomes its flag (`--tilt-shift`).
use lensblur::job::spell_options;

/// The flag of a render-job option: `tilt_shift` is `--tilt-shift`.
pub fn flag(option: &str) -> String {
    format!("--{}", option.replace('_', "-"))
}

/// A library error as the command line says it: the job's refusals (a parameter it names)
/// with flags for option names; every other error unchanged, so its kind (a lost device, an
/// I/O error) stays visible to callers that look for it.
pub fn job_error(error: lensblur::Error) -> anyhow::Error {
    match error {
        lensblur::Error::InvalidParameter { message, .. } => anyhow::anyhow!(spell_options(&message, flag)),
        other => super::input_args::input_flag_error(other),
    }
}
