//! `morphray batch BIDS_DIR OUT_DIR participant|group`: a cohort on BIDS-App conventions (the
//! library does the work: `study::batch` for the participant level, `study::batch_group` for
//! the group level; this file maps arguments and shows progress).
//!
//! Decisions:
//! - Progress is an indicatif bar with the ETA when stderr is a terminal, and one plain line per
//!   scan otherwise (cluster logs, CI), so a log file has no control characters.
//! - A failed scan is a `morphray: warning:` line and a record in OUT_DIR; the other scans go
//!   on. The command then exits 3 (a workflow must notice a hole in the cohort), or 0 with
//!   `--allow-failures` for workflows that read the failure records themselves. It exits 1 when
//!   it cannot run at all (no dataset, no device, an unwritable OUT_DIR, an OUT_DIR that is the
//!   input or another dataset).
//! - The shard comes from `--shard I/N`, else from a Slurm array job's variables, else all.

use super::output::print_line;
use crate::error::Error;
use crate::study::batch::{BatchError, ParticipantOptions, Progress, run_participant};
use crate::study::batch_group::{GroupError, run_group};
use crate::study::bids::Shard;
use clap::{Args, ValueEnum};
use std::io::IsTerminal;
use std::path::PathBuf;

/// BIDS-App analysis level.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum Level {
    /// Each scan: Table-1 row, peaks, windows, warnings and three thumbnails.
    Participant,
    /// All scans: a TSV of the rows and an HTML report, from the participant outputs alone.
    Group,
}

/// Options of `batch`.
#[derive(Debug, Args)]
#[command(
    after_help = "Exit status: 0 when every scan was processed (or finished earlier); 1 when \
the batch could not run (no dataset, no device, an OUT_DIR that cannot be written, is the input \
or holds another dataset's dataset_description.json); 3 when it ran but some scans failed (their \
desc-error records say why; --allow-failures makes this 0); 2 for a usage error."
)]
pub struct BatchArgs {
    /// The BIDS dataset (the folder with the sub-<label> folders).
    pub bids_dir: PathBuf,
    /// The derivatives folder (created; BIDS Derivatives layout).
    pub output_dir: PathBuf,
    /// participant or group.
    #[arg(value_enum)]
    pub level: Level,
    /// Subjects to process (with or without `sub-`); all when not given.
    #[arg(long = "participant-label", num_args = 1.., value_name = "LABEL")]
    pub participant_label: Vec<String>,
    /// Process every N-th scan starting at I (0-based), e.g. 0/4; default: from
    /// SLURM_ARRAY_TASK_ID and SLURM_ARRAY_TASK_COUNT when set, else all scans.
    #[arg(long, value_name = "I/N")]
    pub shard: Option<String>,
    /// Thumbnail width and height, pixels.
    #[arg(long, default_value_t = 256, value_parser = clap::value_parser!(u32).range(16..=2048))]
    pub thumbnail_size: u32,
    /// Peaks only: no thumbnails.
    #[arg(long)]
    pub no_thumbnails: bool,
    /// What the thumbnails show: `brain` (default: the brain of a head scan, as `render`
    /// shows it, so a report meant to be shared shows no faces) or `head` (the whole head,
    /// brain extraction off).
    #[arg(long, value_enum, default_value_t = Thumbnails::Brain, value_name = "WHAT")]
    pub thumbnails: Thumbnails,
    /// Exit 0 even when some scans failed (default: exit 3; the failures are recorded in
    /// OUT_DIR either way).
    #[arg(long)]
    pub allow_failures: bool,
}

/// `--thumbnails`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum Thumbnails {
    /// The brain of a head scan (brain extraction as `render` does it).
    Brain,
    /// The whole head (brain extraction off): faces are identifiable.
    Head,
}

fn batch_error(e: BatchError) -> Error {
    match e {
        BatchError::Bids(e) => Error::Usage(e.to_string()),
        BatchError::Output(e) => Error::Output(e),
        BatchError::Gpu(e) => Error::Gpu(e),
        BatchError::Refused(e) => Error::Usage(e),
    }
}

fn group_error(e: GroupError) -> Error {
    match e {
        GroupError::Output(e) => Error::Output(e),
        other => Error::Usage(other.to_string()),
    }
}

fn shard(args: &BatchArgs) -> Result<Shard, Error> {
    if let Some(text) = &args.shard {
        return Shard::parse(text).map_err(Error::Usage);
    }
    Ok(Shard::from_slurm(|name| std::env::var(name).ok())
        .map_err(Error::Usage)?
        .unwrap_or(Shard::ALL))
}

/// Runs the command.
pub fn run(args: &BatchArgs, global: &super::GlobalOptions) -> Result<(), Error> {
    if args.level == Level::Group {
        if args.shard.is_some() || !args.participant_label.is_empty() {
            return Err(Error::Usage(
                "the group level reads every participant output: drop --shard and \
                 --participant-label"
                    .into(),
            ));
        }
        let report = run_group(&args.output_dir).map_err(group_error)?;
        print_line(&format!(
            "group: {} scans, {} failed; wrote {} and {}",
            report.scans,
            report.failures,
            report.tsv.display(),
            report.html.display()
        ));
        return Ok(());
    }
    let options = ParticipantOptions {
        bids: args.bids_dir.clone(),
        out: args.output_dir.clone(),
        participants: args.participant_label.clone(),
        shard: shard(args)?,
        thumbnail: args.thumbnail_size,
        thumbnails: !args.no_thumbnails,
        head_thumbnails: args.thumbnails == Thumbnails::Head,
    };
    let terminal = std::io::stderr().is_terminal();
    let mut bar: Option<indicatif::ProgressBar> = None;
    let mut index = 0usize;
    let mut total = 0usize;
    let mut progress = |event: Progress<'_>| match event {
        Progress::Start { todo, skipped } => {
            total = todo;
            eprintln!(
                "morphray: batch: {todo} scans to process, {skipped} finished earlier (skipped)"
            );
            if terminal {
                let b = indicatif::ProgressBar::new(todo as u64);
                if let Ok(style) = indicatif::ProgressStyle::with_template(
                    "{bar:40} {pos}/{len} scans  {per_sec}  ETA {eta}  {msg}",
                ) {
                    b.set_style(style);
                }
                bar = Some(b);
            }
        }
        Progress::Scan {
            scan,
            error,
            timings,
        } => {
            index += 1;
            if let Some(message) = error {
                let line = format!("morphray: warning: {} skipped: {message}", scan.relative);
                match &bar {
                    Some(b) => b.println(line),
                    None => eprintln!("{line}"),
                }
            }
            match &bar {
                Some(b) => {
                    b.set_message(scan.relative.clone());
                    b.inc(1);
                }
                None if error.is_none() => eprintln!(
                    "morphray: batch: [{index}/{total}] {} ({:.0} ms)",
                    scan.relative, timings.total_ms
                ),
                None => {}
            }
        }
    };
    let report =
        run_participant(&options, &global.engine_config(), &mut progress).map_err(batch_error)?;
    if let Some(b) = bar {
        b.finish_and_clear();
    }
    for note in &report.notes {
        eprintln!("morphray: note: {note}");
    }
    print_line(&format!(
        "participant: {} scans: {} done, {} skipped (finished earlier), {} failed in {:.1} s; log {}",
        report.scans,
        report.done,
        report.skipped,
        report.failed,
        report.wall_s,
        report.log.display()
    ));
    if report.failed > 0 && !args.allow_failures {
        return Err(Error::ScansFailed(format!(
            "{} of {} scans failed (their desc-error records in {} say why); exit status {} \
             (--allow-failures makes it 0)",
            report.failed,
            report.scans,
            args.output_dir.display(),
            Error::SCANS_FAILED_EXIT
        )));
    }
    Ok(())
}
