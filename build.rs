//! Build script (shader compilation lands with the gpu layer).
fn main() {}
