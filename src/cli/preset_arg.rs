//! `--preset NAME|list` on render, view and peaks: the look by modality (`scene::preset`, the
//! library's one table; this file only parses and prints it).
//!
//! Decisions:
//! - `--preset list` prints the table (one line each) and exits 0 before the rest of the
//!   command line is checked, so `morphray render --preset list` needs no input or `-o`.
//! - An unknown name is a one-line usage error listing the valid names.

use crate::scene::Preset;

/// What `--preset` says: a preset, or `list`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PresetArg {
    /// Print the table and exit.
    List,
    /// Use this preset instead of the automatic choice.
    Named(Preset),
}

impl PresetArg {
    /// The preset named, if one was.
    pub fn preset(arg: Option<PresetArg>) -> Option<Preset> {
        match arg {
            Some(PresetArg::Named(p)) => Some(p),
            _ => None,
        }
    }
}

impl serde::Serialize for PresetArg {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        s.serialize_str(match self {
            PresetArg::List => "list",
            PresetArg::Named(p) => p.name(),
        })
    }
}

/// clap's parser for `--preset`.
pub fn parse_preset(text: &str) -> Result<PresetArg, String> {
    if text.trim().eq_ignore_ascii_case("list") {
        return Ok(PresetArg::List);
    }
    Preset::parse(text)
        .map(PresetArg::Named)
        .ok_or_else(|| format!("unknown preset `{text}`; use {} (or list)", Preset::names()))
}

/// The table as `--preset list` prints it.
pub fn list_text() -> String {
    crate::scene::preset::PRESETS
        .iter()
        .map(|(p, summary)| format!("{:<14} {summary}", p.name()))
        .collect::<Vec<_>>()
        .join("\n")
}

/// Whether the command line asks for `--preset list` on render, view or peaks.
pub fn asks_for_list(args: &[String]) -> bool {
    let command = args.iter().skip(1).find(|a| !a.starts_with('-'));
    if !matches!(
        command.map(String::as_str),
        Some("render" | "view" | "peaks")
    ) {
        return false;
    }
    args.windows(2)
        .any(|w| w[0] == "--preset" && w[1].eq_ignore_ascii_case("list"))
        || args.iter().any(|a| a.eq_ignore_ascii_case("--preset=list"))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn list_is_recognised_only_as_the_value_of_preset_on_the_three_commands() {
        let argv = |s: &str| s.split(' ').map(String::from).collect::<Vec<_>>();
        assert!(asks_for_list(&argv("morphray render --preset list")));
        assert!(asks_for_list(&argv("morphray peaks --preset=list")));
        assert!(!asks_for_list(&argv("morphray info --preset list")));
        assert!(!asks_for_list(&argv("morphray render list.nii -o x.png")));
        assert!(parse_preset("nope").unwrap_err().contains("mr, ct, angio"));
        assert_eq!(parse_preset("CT"), Ok(PresetArg::Named(Preset::Ct)));
        assert_eq!(list_text().lines().count(), Preset::ALL.len());
    }
}
