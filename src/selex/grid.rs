//! See the module list in `selex` (mod.rs).
