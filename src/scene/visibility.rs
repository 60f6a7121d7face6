//! Why a scene can show nothing: the reason a render came out as bare background, in words.
//!
//! Decisions: an empty image is never silent (issue 11). Most causes are decidable from the scene
//! alone, before any pixel exists (a constant volume, every tissue switched off, no window for
//! any visible tissue, zero opacity), so the viewer can say so over the image every frame without
//! reading pixels back; the remaining cause (windows exist but no sample falls in them) needs the
//! image, which the CLI has. Each client words its own "what to try" (flags on the command line,
//! the histogram's bands in the viewer); the reason itself is shared.

use super::{RenderMode, Scene, TissueClass};

/// Why a scene shows only the background.
#[derive(Clone, Debug, PartialEq)]
pub enum EmptyScene {
    /// Every finite voxel has the same intensity (or none is finite): I_norm is 0 everywhere.
    ConstantVolume,
    /// DVR with every tissue switched off.
    AllHidden,
    /// DVR whose visible tissues have no window (their histogram peak was not found).
    NoWindow(Vec<TissueClass>),
    /// DVR whose visible tissues with a window all have opacity 0.
    ZeroOpacity(Vec<TissueClass>),
    /// Known only from the image: windows exist, but no sample met one with a non-zero gradient
    /// (or, in MIP/MinIP, every ray stayed at the display window's black point).
    NothingSampled,
}

impl EmptyScene {
    /// The reason, one sentence without a final stop, independent of the client.
    pub fn reason(&self) -> String {
        let names = |ts: &[TissueClass]| ts.iter().map(|t| t.name()).collect::<Vec<_>>().join(", ");
        match self {
            EmptyScene::ConstantVolume => {
                "the volume is constant (every finite voxel has the same intensity, or none is \
                 finite), so there is nothing to classify"
                    .into()
            }
            EmptyScene::AllHidden => "every tissue is switched off".into(),
            EmptyScene::NoWindow(ts) => format!(
                "no histogram peak was found for {}, so no tissue window exists to show",
                names(ts)
            ),
            EmptyScene::ZeroOpacity(ts) => {
                format!("every visible tissue ({}) has opacity 0", names(ts))
            }
            EmptyScene::NothingSampled => {
                "no sample along any ray fell inside a visible tissue window".into()
            }
        }
    }
}

/// What makes `scene` show nothing, when that is known without rendering. `constant`: the
/// volume's normalization found a single intensity (or none).
pub fn predict_empty(scene: &Scene, constant: bool) -> Option<EmptyScene> {
    if constant {
        return Some(EmptyScene::ConstantVolume);
    }
    if scene.effects.mode != RenderMode::Dvr {
        return None;
    }
    let visible: Vec<TissueClass> = TissueClass::ALL
        .into_iter()
        .filter(|&t| scene.classification.style(t).visible)
        .collect();
    if visible.is_empty() {
        return Some(EmptyScene::AllHidden);
    }
    let windowed: Vec<TissueClass> = visible
        .iter()
        .copied()
        .filter(|&t| scene.classification.style(t).window.is_some())
        .collect();
    if windowed.is_empty() {
        return Some(EmptyScene::NoWindow(visible));
    }
    if windowed
        .iter()
        .all(|&t| scene.classification.style(t).opacity <= 0.0)
    {
        return Some(EmptyScene::ZeroOpacity(windowed));
    }
    None
}

/// Pixels of an RGBA8 image that differ from the background colour by more than rounding.
pub fn pixels_off_background(rgba8: &[u8], background: [f32; 3]) -> usize {
    let bg = background.map(|c| (c.clamp(0.0, 1.0) * 255.0).round() as i16);
    rgba8
        .chunks_exact(4)
        .filter(|p| (0..3).any(|c| (p[c] as i16 - bg[c]).abs() > 1))
        .count()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::{Classification, Window};

    fn scene() -> Scene {
        let w = Some(Window {
            lo: 0.2,
            hi: 0.4,
            edge: 0.01,
        });
        Scene::new(Classification::with_windows([w, None, w, None]))
    }

    #[test]
    fn each_decidable_cause_is_named() {
        let mut s = scene();
        assert_eq!(predict_empty(&s, false), None);
        assert_eq!(predict_empty(&s, true), Some(EmptyScene::ConstantVolume));
        s.classification.show_only(&[TissueClass::Gm]);
        assert_eq!(
            predict_empty(&s, false),
            Some(EmptyScene::NoWindow(vec![TissueClass::Gm]))
        );
        s.classification.show_only(&[]);
        assert_eq!(predict_empty(&s, false), Some(EmptyScene::AllHidden));
        s.classification
            .show_only(&[TissueClass::Csf, TissueClass::Gm]);
        s.classification.style_mut(TissueClass::Csf).opacity = 0.0;
        assert_eq!(
            predict_empty(&s, false),
            Some(EmptyScene::ZeroOpacity(vec![TissueClass::Csf]))
        );
        // MIP shows values, not tissues: only a constant volume is known to be empty.
        s.effects.mode = RenderMode::Mip;
        assert_eq!(predict_empty(&s, false), None);
        assert!(
            EmptyScene::NoWindow(vec![TissueClass::Csf, TissueClass::Wm])
                .reason()
                .contains("csf, wm")
        );
    }

    #[test]
    fn background_pixels_are_told_apart_within_rounding() {
        let image = [0, 0, 0, 255, 1, 0, 0, 255, 0, 9, 0, 255];
        assert_eq!(pixels_off_background(&image, [0.0; 3]), 1);
        assert_eq!(pixels_off_background(&[255, 255, 255, 255], [1.0; 3]), 0);
    }
}
