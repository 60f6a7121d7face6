//! `--view anterior|posterior|left|right|superior|inferior`: the viewer's standard views on the
//! command line (the table is `scene::views`, so both agree; superior and inferior put anterior
//! at the top).

use crate::scene::views::StandardView;
use clap::Args;

/// A standard view instead of --azimuth/--elevation.
#[derive(Debug, Clone, Default, Args, serde::Serialize)]
#[command(next_help_heading = "Scene")]
pub struct ViewPresetArgs {
    /// A standard view: anterior, posterior, left, right, superior or inferior (or the initial).
    ///
    /// Superior and inferior show anterior at the top, as radiologists expect.
    #[arg(long = "view", value_name = "NAME", value_parser = parse_view, conflicts_with_all = ["azimuth", "elevation"])]
    #[serde(serialize_with = "view_name")]
    pub view: Option<StandardView>,
}

impl ViewPresetArgs {
    /// (azimuth, elevation) in degrees, when a view was named.
    pub fn angles(&self) -> Option<(f64, f64)> {
        self.view.map(StandardView::angles)
    }
}

fn parse_view(text: &str) -> Result<StandardView, String> {
    StandardView::parse(text).ok_or_else(|| {
        format!("unknown view `{text}`; use anterior, posterior, left, right, superior or inferior")
    })
}

fn view_name<S: serde::Serializer>(view: &Option<StandardView>, s: S) -> Result<S::Ok, S::Error> {
    s.serialize_str(view.map_or("", |v| v.name()))
}
