//! Command-line pieces shared by the jump examples (a folder, not `common.rs`, so cargo does
//! not take it for an example of its own).

use anyhow::Context;
use legwork::jump::Jump;
use legwork::terrain::{Plane, Terrain};

/// Removes `flag VALUE` from `args` and returns `VALUE` (`None` without the flag).
pub fn take(args: &mut Vec<String>, flag: &str) -> anyhow::Result<Option<String>> {
    match args.iter().position(|a| a == flag) {
        Some(i) => {
            let value = args.get(i + 1).with_context(|| format!("{flag}: a value"))?.clone();
            args.drain(i..i + 2);
            Ok(Some(value))
        }
        None => Ok(None),
    }
}

/// `--jump NAME` (removed from `args`): the jump's terrain (an embedded jump or a jump file), its box included; flat
/// ground at z = 0 without the flag.
pub fn jump_terrain(args: &mut Vec<String>) -> anyhow::Result<Box<dyn Terrain>> {
    Ok(match take(args, "--jump")? {
        Some(name) => Box::new(Jump::load(&name)?.terrain()),
        None => Box::new(Plane::flat(0.0)),
    })
}
