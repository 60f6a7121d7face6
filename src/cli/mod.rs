//! The command-line layer: argument parsing, commands, output. No Vulkan calls of its own.
//!
//! Decisions: every command returns `Result<(), Error>`; `main` prints an error as exactly one
//! line on stderr (`morphray: ...`) and exits with status 1 (clap's usage errors exit with 2).
//! A panic, which would be a bug, is also reported as one line.

mod accuracy;
pub mod args;
mod bench;
mod devices;
mod info;
pub mod output;
mod peaks;
pub mod png;
pub mod render;
pub mod session;
pub mod source;
mod view;

use crate::error::Error;
use args::{Cli, Command};
use clap::Parser;
use std::process::ExitCode;

/// Runs the command line and returns the process exit status.
pub fn main() -> ExitCode {
    std::panic::set_hook(Box::new(|info| {
        let message = info
            .payload()
            .downcast_ref::<&str>()
            .map(|s| s.to_string())
            .or_else(|| info.payload().downcast_ref::<String>().cloned())
            .unwrap_or_else(|| "unknown".into());
        let place = info
            .location()
            .map(|l| format!(" at {}:{}", l.file(), l.line()))
            .unwrap_or_default();
        eprintln!("morphray: internal error (a bug, please report it): {message}{place}");
    }));
    let cli = Cli::parse();
    match run(&cli) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("morphray: {}", one_line(&e.to_string()));
            ExitCode::FAILURE
        }
    }
}

fn one_line(text: &str) -> String {
    text.split_whitespace().collect::<Vec<_>>().join(" ")
}

/// Dispatches a parsed command line.
pub fn run(cli: &Cli) -> Result<(), Error> {
    let device = cli.device.as_deref();
    match &cli.command {
        Command::Info(args) => info::run(args),
        Command::Peaks(args) => peaks::run(args, device, cli.validation),
        Command::Render(args) => render::run(args, device, cli.validation),
        Command::View(args) => view::run(args, device, cli.validation),
        Command::Bench(args) => bench::run(args, device, cli.validation),
        Command::Accuracy(args) => accuracy::run(args, device, cli.validation),
        Command::Devices => devices::run(),
        Command::Phantom(args) => {
            let spec = crate::volume::phantom::PhantomSpec {
                dims: args.dims,
                ..crate::volume::phantom::PhantomSpec::cohort_a()
            };
            let phantom = crate::volume::phantom::generate(&spec)?;
            let gzip = args.output.extension().is_some_and(|e| e == "gz");
            crate::volume::nifti::write_nifti1(&phantom.volume, &args.output, gzip)?;
            output::print_line(&format!(
                "wrote {} ({}x{}x{}, int16, 1 mm)",
                args.output.display(),
                args.dims[0],
                args.dims[1],
                args.dims[2]
            ));
            Ok(())
        }
    }
}
