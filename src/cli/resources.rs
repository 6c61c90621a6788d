//! Resource bounds checked before work starts: the memory a solve or a simulation will
//! need, estimated from its size and refused above a limit (default: half of this
//! machine's memory; `--memory-limit GB` sets it).

use anyhow::Result;
use legwork::job::resources::MemoryLimit;

/// Set once from `--memory-limit` before a command runs (GB).
pub(crate) static MEMORY_LIMIT_GB: std::sync::OnceLock<Option<f64>> = std::sync::OnceLock::new();

/// The limit `--memory-limit` sets (default: half of this machine's memory).
pub(crate) fn memory_limit() -> MemoryLimit<'static> {
    MemoryLimit { gb: MEMORY_LIMIT_GB.get().copied().flatten(), setting: "--memory-limit GB" }
}

/// Parses `--memory-limit` (GB, positive and finite).
pub(crate) fn parse_gigabytes(text: &str) -> Result<f64, String> {
    match text.parse::<f64>() {
        Ok(gb) if gb.is_finite() && gb > 0.0 => Ok(gb),
        _ => Err(format!("expected a positive number of gigabytes, got {text}")),
    }
}
