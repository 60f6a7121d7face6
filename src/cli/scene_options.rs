//! The scene options as data, for clients that are not the command line (issue 32 item 3).
//!
//! Decisions:
//! - One option model: [`SceneArgs`]' own clap definition. The Python package lists the
//!   options with [`scene_options`] and hands its keyword arguments back as the words a shell
//!   would pass ([`parse_scene_args`]), so a name, a unit, a default or a check cannot differ
//!   between `morphray render` and `Volume.render()`, and an option added to the command line
//!   reaches Python without a second list (tests/python walks this list).
//! - Each option says how a client spells its value ([`OptionKind`]): a switch, one value, a
//!   comma-separated list, or a repeatable `NAME=VALUE` entry. The conversion of a client's
//!   native values (a tuple for `--size`, a dict for `--window`) is the client's; the parsing
//!   and every check stay here.

use super::scene_args::SceneArgs;
use crate::error::Error;
use clap::{ArgAction, Args, Command, FromArgMatches};

/// How an option's value is written.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum OptionKind {
    /// Present or absent (`--no-jitter`).
    Flag,
    /// One value (`--step 0.25`).
    Value,
    /// One comma-separated list (`--tissues gm,wm`).
    List,
    /// Repeatable, one value each time (`--window wm=0.7:0.9 --window gm=0.5:0.7`).
    Repeated,
}

/// One scene option of the command line.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct SceneOption {
    /// The long name without dashes, as the command line spells it (`clip-plane`).
    pub long: String,
    /// How its value is written.
    pub kind: OptionKind,
    /// The values it accepts, when it has a closed set (`dvr`, `mip`, `minip`).
    pub values: Vec<String>,
    /// Its default, as the command line would write it; empty when it has none.
    pub default: String,
    /// The first line of its help.
    pub help: String,
}

/// The scene options' clap command (no binary name: every word is an option or its value).
fn scene_command() -> Command {
    SceneArgs::augment_args(Command::new("scene").no_binary_name(true))
}

/// Every scene option `render`, `view`, `bench`, `plan`, `kernels` and `accuracy` accept.
pub fn scene_options() -> Vec<SceneOption> {
    let command = scene_command();
    command
        .get_arguments()
        .filter_map(|arg| {
            let long = arg.get_long()?.to_string();
            let kind = match arg.get_action() {
                ArgAction::SetTrue | ArgAction::SetFalse | ArgAction::Count => OptionKind::Flag,
                ArgAction::Append if arg.get_value_delimiter().is_some() => OptionKind::List,
                ArgAction::Append => OptionKind::Repeated,
                _ => OptionKind::Value,
            };
            let values = arg
                .get_possible_values()
                .iter()
                .filter(|v| !v.is_hide_set())
                .map(|v| v.get_name().to_string())
                .collect();
            let default = arg
                .get_default_values()
                .iter()
                .map(|v| v.to_string_lossy().into_owned())
                .collect::<Vec<_>>()
                .join(",");
            let help = arg
                .get_help()
                .map(|h| h.to_string().lines().next().unwrap_or_default().to_string())
                .unwrap_or_default();
            (kind != OptionKind::Flag || long != "help").then_some(SceneOption {
                long,
                kind,
                values,
                default,
                help,
            })
        })
        .collect()
}

/// The scene arguments the command-line words `words` describe (`["--mode", "mip", ...]`),
/// parsed and checked exactly as `morphray render` parses them. A bad name or value is a
/// usage error with clap's first line (`invalid value 'x' for '--mode <MODE>'...`).
pub fn parse_scene_args(words: &[String]) -> Result<SceneArgs, Error> {
    let matches = scene_command()
        .try_get_matches_from(words)
        .map_err(|e| Error::Usage(first_line(&e.to_string())))?;
    SceneArgs::from_arg_matches(&matches).map_err(|e| Error::Usage(first_line(&e.to_string())))
}

/// clap's message without its `error: ` prefix and usage lines.
fn first_line(text: &str) -> String {
    let line = text.lines().next().unwrap_or_default();
    line.strip_prefix("error: ").unwrap_or(line).to_string()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn words(text: &str) -> Vec<String> {
        text.split_whitespace().map(String::from).collect()
    }

    #[test]
    fn every_scene_option_is_listed_with_its_kind() {
        let options = scene_options();
        let kind = |name: &str| options.iter().find(|o| o.long == name).map(|o| o.kind);
        assert_eq!(kind("mode"), Some(OptionKind::Value));
        assert_eq!(kind("no-jitter"), Some(OptionKind::Flag));
        assert_eq!(kind("tissues"), Some(OptionKind::List));
        assert_eq!(kind("window"), Some(OptionKind::Repeated));
        assert_eq!(kind("clip-plane"), Some(OptionKind::Repeated));
        assert_eq!(kind("view"), Some(OptionKind::Value));
        assert_eq!(kind("help"), None);
        let mode = options.iter().find(|o| o.long == "mode").unwrap();
        assert_eq!(mode.values, ["dvr", "mip", "minip"]);
        assert_eq!(mode.default, "dvr");
    }

    #[test]
    fn words_parse_as_the_command_line_parses_them() {
        let args = parse_scene_args(&words(
            "--mode mip --tissues gm,wm --window wm=0.7:0.9 --window gm=0.5:0.6 --no-jitter",
        ))
        .unwrap();
        assert_eq!(args.tissues, ["gm", "wm"]);
        assert_eq!(args.window.len(), 2);
        assert!(args.no_jitter);
        let defaults = parse_scene_args(&[]).unwrap();
        assert_eq!(defaults.step, 0.5);
        assert!(defaults.shading.is_none());
    }

    #[test]
    fn a_bad_value_is_a_usage_error_naming_the_option() {
        let Err(Error::Usage(message)) = parse_scene_args(&words("--mode sideways")) else {
            panic!("expected a usage error");
        };
        assert!(message.contains("--mode"), "{message}");
        assert!(!message.starts_with("error:"), "{message}");
        let Err(Error::Usage(message)) = parse_scene_args(&words("--step nan")) else {
            panic!("expected a usage error");
        };
        assert!(message.contains("--step"), "{message}");
    }
}
