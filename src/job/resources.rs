//! Resource bounds checked before work starts: the memory a solve or a simulation will
//! need, estimated from its size and refused above a limit (default: half of this
//! machine's memory).

use super::JobError;

/// This machine's memory (bytes), from `/proc/meminfo`.
pub fn machine_memory() -> Option<u64> {
    let text = std::fs::read_to_string("/proc/meminfo").ok()?;
    let line = text.lines().find(|l| l.starts_with("MemTotal:"))?;
    let kib: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kib * 1024)
}

/// The memory limit of a job: `gb` if the caller set one, else half of this machine's
/// memory; `setting` names how a user sets it (`--memory-limit GB`, `memory_limit_gb=`).
#[derive(Clone, Copy, Debug)]
pub struct MemoryLimit<'a> {
    pub gb: Option<f64>,
    pub setting: &'a str,
}

/// Refuses `what` (bad input) if its estimated memory passes the limit; `smaller` says how
/// to shrink the job.
pub fn check_memory(what: &str, estimate_bytes: f64, smaller: &str, limit: MemoryLimit) -> Result<(), JobError> {
    let (bytes, source) = match limit.gb {
        // `--memory-limit 16` on the command line, `memory_limit_gb=16` in Python.
        Some(gb) => match limit.setting.strip_suffix(" GB") {
            Some(flag) => (gb * 1e9, format!("{flag} {gb}")),
            None => (gb * 1e9, format!("{}={gb}", limit.setting)),
        },
        None => match machine_memory() {
            Some(total) => (total as f64 / 2.0, format!("half of this machine's {:.1} GB", total as f64 / 1e9)),
            None => return Err(JobError::bad_input(format!("{what}: cannot read this machine's memory from /proc/meminfo to bound the run; set {}", limit.setting))),
        },
    };
    if estimate_bytes > bytes {
        return Err(JobError::bad_input(format!(
            "{what} would need about {:.1} GB of memory, over the limit of {:.1} GB ({source}); {smaller}, or raise the limit with {}",
            estimate_bytes / 1e9,
            bytes / 1e9,
            limit.setting
        )));
    }
    Ok(())
}
