//! The MuJoCo checker for the tests that run MuJoCo.

use legwork::export::MujocoCheck;

/// The checker, or `None` (the test skips) when its environment is missing outside CI; with
/// `CI` set a missing checker fails the test.
pub fn mujoco_or_skip() -> Option<MujocoCheck> {
    match MujocoCheck::locate() {
        Ok(check) => Some(check),
        Err(e) if std::env::var_os("CI").is_some() => panic!("{e}, and CI is set"),
        Err(e) => {
            eprintln!("skipped: {e}");
            None
        }
    }
}
