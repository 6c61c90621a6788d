pub mod control;
pub mod trials;
