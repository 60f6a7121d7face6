//! The `morphray` command-line tool; all logic lives in the library's `cli` layer.
fn main() -> std::process::ExitCode {
    morphray::cli::main()
}
