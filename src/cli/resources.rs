//! Resource bounds checked before work starts: the memory a solve or a simulation will
//! need, estimated from its size and refused above a limit (default: half of this
//! machine's memory; `--memory-limit GB` sets it).

use anyhow::{bail, Result};

/// Set once from `--memory-limit` before a command runs (GB).
pub(crate) static MEMORY_LIMIT_GB: std::sync::OnceLock<Option<f64>> = std::sync::OnceLock::new();

/// This machine's memory (bytes), from `/proc/meminfo`.
fn machine_memory() -> Option<u64> {
    let text = std::fs::read_to_string("/proc/meminfo").ok()?;
    let line = text.lines().find(|l| l.starts_with("MemTotal:"))?;
    let kib: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kib * 1024)
}

/// The limit (bytes) and where it comes from, for the message.
fn memory_limit() -> Result<(u64, String)> {
    if let Some(Some(gb)) = MEMORY_LIMIT_GB.get() {
        return Ok(((gb * 1e9) as u64, format!("--memory-limit {gb}")));
    }
    match machine_memory() {
        Some(total) => Ok((total / 2, format!("half of this machine's {:.1} GB", total as f64 / 1e9))),
        None => bail!("cannot read this machine's memory from /proc/meminfo to bound the run; give --memory-limit GB"),
    }
}

/// Refuses `what` if its estimated memory passes the limit; `smaller` says how to shrink it.
pub(crate) fn check_memory(what: &str, estimate_bytes: f64, smaller: &str) -> Result<()> {
    let (limit, source) = memory_limit()?;
    if estimate_bytes > limit as f64 {
        bail!(
            "{what} would need about {:.1} GB of memory, over the limit of {:.1} GB ({source}); {smaller}, or raise the limit with --memory-limit GB",
            estimate_bytes / 1e9,
            limit as f64 / 1e9
        );
    }
    Ok(())
}

/// Parses `--memory-limit` (GB, positive and finite).
pub(crate) fn parse_gigabytes(text: &str) -> Result<f64, String> {
    match text.parse::<f64>() {
        Ok(gb) if gb.is_finite() && gb > 0.0 => Ok(gb),
        _ => Err(format!("expected a positive number of gigabytes, got {text}")),
    }
}
