//! Which stack commands open without `--series`, and, when none qualifies, why and what to do
//! in one line.
//!
//! Decisions: the default is the largest image stack of at least two slices (most voxels; ties:
//! the first listed). Without one, the line names the common cases (one 2-D slice; every file
//! its own series, as some anonymizers write them) and otherwise counts the stacks of each kind
//! rather than listing them (issue 30: a 2884-character line for 130 one-file series).

use super::series::{Role, Stack};
use std::path::Path;

/// The largest stack (most voxels) among `candidates` with a layout; `volumes_only`: image
/// stacks of at least two slices.
pub fn best(
    stacks: &[Stack],
    candidates: impl Iterator<Item = usize>,
    volumes_only: bool,
) -> Option<usize> {
    let mut best: Option<(usize, usize)> = None;
    for i in candidates {
        let Ok(layout) = &stacks[i].layout else {
            continue;
        };
        if volumes_only && (stacks[i].role != Role::Image || layout.dims[2] < 2) {
            continue;
        }
        let voxels = layout.dims.iter().product::<usize>();
        if best.is_none_or(|(_, v)| voxels > v) {
            best = Some((i, voxels));
        }
    }
    best.map(|(i, _)| i)
}

/// Why no stack is a default, and what to do, in one line (issue 30: this was a list of every
/// stack, 2884 characters for 130 one-file series).
pub fn why_no_default(stacks: &[Stack], path: &Path) -> String {
    let info = format!("`morphray info {}` lists them", path.display());
    let single = |s: &Stack| s.layout.as_ref().is_ok_and(|l| l.dims[2] == 1);
    if let [one] = stacks
        && single(one)
        && one.role == Role::Image
    {
        let dims = one.layout.as_ref().map(|l| l.dims).unwrap_or_default();
        // A mosaic whose tiles could not be cut says so (series.rs's warning).
        let mosaic = one
            .layout
            .as_ref()
            .ok()
            .and_then(|l| l.warnings.iter().find(|w| w.contains("MOSAIC")))
            .map(|w| format!(" ({w})"))
            .unwrap_or_default();
        return format!(
            "it holds one 2-D slice ({}x{}), not a 3-D volume; give the folder of its whole \
             series, or open the slice itself with --series 0{mosaic}",
            dims[0], dims[1]
        );
    }
    let mut uids: Vec<&str> = stacks.iter().map(|s| s.uid.as_str()).collect();
    uids.sort_unstable();
    uids.dedup();
    if stacks.len() > 1 && stacks.iter().all(single) && uids.len() == stacks.len() {
        return format!(
            "every one of its {} image files is its own series (a SeriesInstanceUID per file, \
             as some anonymizers write them), so none forms a 3-D stack; give a folder of one \
             series whose files share their SeriesInstanceUID, or open one slice with --series \
             ({info})",
            stacks.len()
        );
    }
    // Count stacks of each kind rather than list them all.
    let mut kinds: Vec<(String, usize)> = Vec::new();
    for s in stacks {
        let kind = match &s.layout {
            Err(e) => format!("{:?} that forms no volume ({e})", s.role).to_lowercase(),
            Ok(l) => format!("{:?} of {} slice(s)", s.role, l.dims[2]).to_lowercase(),
        };
        match kinds.iter_mut().find(|(k, _)| *k == kind) {
            Some((_, n)) => *n += 1,
            None => kinds.push((kind, 1)),
        }
    }
    let shown: Vec<String> = kinds
        .iter()
        .take(3)
        .map(|(k, n)| format!("{n} {k}"))
        .collect();
    let more = kinds.len().saturating_sub(3);
    format!(
        "no series is a 3-D image stack ({}{}); choose one with --series ({info})",
        shown.join("; "),
        if more > 0 {
            format!("; {more} other kind(s)")
        } else {
            String::new()
        }
    )
}
