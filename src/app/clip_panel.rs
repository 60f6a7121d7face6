//! The viewer's "Crop, clip and colour" panel (issue 16 items 2 and 4): crop sliders per voxel
//! axis, one clip plane across a world axis, and the colour map.
//!
//! Decisions: the panel keeps no state of its own; it reads and writes `Scene::clip` and
//! `Scene::colormap`, so scripts, the command line (`view --crop ...`) and the panel always agree
//! and a change is a uniform write like every other control. The panel edits the first clip
//! plane only, as an axis-aligned cut (axis, position in world mm, which side is kept); planes
//! given on the command line beyond the first are kept and shown as a count.

use crate::scene::{ClipPlane, Colormap, Scene};
use egui::Ui;

/// Narrowest crop range the sliders allow (a fraction of the axis).
const MIN_CROP: f64 = 0.01;

/// Draws the panel. `extent_mm`: largest side of the volume (the plane's drag speed).
pub fn clip_panel(ui: &mut Ui, scene: &mut Scene, extent_mm: f64) {
    egui::CollapsingHeader::new("Crop, clip and colour")
        .default_open(false)
        .show(ui, |ui| {
            crop_sliders(ui, scene);
            ui.separator();
            plane_controls(ui, scene, extent_mm);
            ui.separator();
            colormap_choice(ui, scene);
        });
}

fn crop_sliders(ui: &mut Ui, scene: &mut Scene) {
    ui.label("Crop (fractions of the voxel axes)");
    for (axis, name) in ["X", "Y", "Z"].iter().enumerate() {
        let [lo, hi] = &mut scene.clip.crop[axis];
        ui.horizontal(|ui| {
            ui.label(*name);
            ui.add(egui::Slider::new(lo, 0.0..=1.0 - MIN_CROP).fixed_decimals(2));
            ui.add(egui::Slider::new(hi, MIN_CROP..=1.0).fixed_decimals(2));
        });
        // Keep lo < hi whichever slider moved.
        if *hi < *lo + MIN_CROP {
            *hi = (*lo + MIN_CROP).min(1.0);
            *lo = lo.min(*hi - MIN_CROP);
        }
    }
    if ui.button("Uncrop").clicked() {
        scene.clip.crop = [[0.0, 1.0]; 3];
    }
}

/// The first plane as (axis, keep the side above?, position mm) when it is axis-aligned.
fn axis_plane(plane: &ClipPlane) -> Option<(usize, bool, f64)> {
    let axis = (0..3).find(|&a| plane.normal[a] != 0.0)?;
    if (0..3).any(|a| a != axis && plane.normal[a] != 0.0) {
        return None;
    }
    let n = plane.normal[axis];
    Some((axis, n > 0.0, -plane.offset_mm / n))
}

fn plane_controls(ui: &mut Ui, scene: &mut Scene, extent_mm: f64) {
    let mut on = scene.clip.planes[0].is_some();
    ui.checkbox(&mut on, "Clip plane")
        .on_hover_text("Cut the volume across a world axis (RAS+ mm); rays start on the cut");
    if !on {
        scene.clip.planes[0] = None;
        return;
    }
    let current = scene.clip.planes[0].unwrap_or(ClipPlane {
        normal: [1.0, 0.0, 0.0],
        offset_mm: 0.0,
    });
    let Some((mut axis, mut above, mut position)) = axis_plane(&current) else {
        ui.label("(an oblique plane from the command line)");
        scene.clip.planes[0] = Some(current);
        return;
    };
    ui.horizontal(|ui| {
        for (a, name) in ["x (R-L)", "y (A-P)", "z (S-I)"].iter().enumerate() {
            if ui.selectable_label(axis == a, *name).clicked() {
                axis = a;
            }
        }
    });
    // A drag value, not a slider: the world position of a volume is anywhere (MNI space is
    // centred on 0 mm, a scanner's volume need not be); dragging across it takes ~200 pixels.
    ui.horizontal(|ui| {
        ui.label("at");
        ui.add(
            egui::DragValue::new(&mut position)
                .speed(extent_mm.max(1.0) / 200.0)
                .suffix(" mm"),
        );
    });
    ui.checkbox(&mut above, "keep the side above (towards +axis)");
    let sign = if above { 1.0 } else { -1.0 };
    let mut normal = [0.0; 3];
    normal[axis] = sign;
    scene.clip.planes[0] = Some(ClipPlane {
        normal,
        offset_mm: -sign * position,
    });
    let more = scene.clip.planes[1..].iter().flatten().count();
    if more > 0 {
        ui.label(format!("and {more} plane(s) from the command line"));
    }
}

fn colormap_choice(ui: &mut Ui, scene: &mut Scene) {
    let label = |m: Option<Colormap>| m.map_or("tissue colours / grey", Colormap::name);
    egui::ComboBox::from_label("Colour map")
        .selected_text(label(scene.colormap))
        .show_ui(ui, |ui| {
            ui.selectable_value(&mut scene.colormap, None, label(None));
            for map in Colormap::ALL {
                ui.selectable_value(&mut scene.colormap, Some(map), map.name());
            }
        })
        .response
        .on_hover_text("MIP/MinIP: the display window's colours; DVR: instead of tissue colours");
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn script_verbs_for_crop_clip_and_colour_parse_or_name_the_problem() {
        use crate::app::script::{Action, parse};
        let steps = parse(
            "crop 0:1,0.2:0.8,0.5:1\nclip -1 0 0 2.5\nclip off\ncolormap Hot\ncolormap off\n",
            "t",
        )
        .unwrap();
        let actions: Vec<Action> = steps.into_iter().map(|s| s.action).collect();
        assert_eq!(
            actions[0],
            Action::Crop([[0.0, 1.0], [0.2, 0.8], [0.5, 1.0]])
        );
        assert_eq!(
            actions[1],
            Action::Clip(Some(ClipPlane {
                normal: [-1.0, 0.0, 0.0],
                offset_mm: 2.5
            }))
        );
        assert_eq!(actions[2], Action::Clip(None));
        assert_eq!(actions[3], Action::Colormap(Some(Colormap::Hot)));
        assert_eq!(actions[4], Action::Colormap(None));
        for (bad, needle) in [
            ("crop 0:1,0:1", "three ranges"),
            ("crop 0:1,0.9:0.1,0:1", "--crop Y"),
            ("clip 0 0 0 1", "zero"),
            ("clip 1 0", "NZ"),
            ("colormap jet", "unknown colour map"),
        ] {
            let e = parse(bad, "t").unwrap_err();
            assert!(e.message.contains(needle), "{bad}: {e}");
        }
    }

    #[test]
    fn axis_planes_round_trip_and_oblique_ones_are_recognized() {
        let p = ClipPlane {
            normal: [0.0, -1.0, 0.0],
            offset_mm: 12.5,
        };
        assert_eq!(axis_plane(&p), Some((1, false, 12.5)));
        let p = ClipPlane {
            normal: [2.0, 0.0, 0.0],
            offset_mm: -8.0,
        };
        assert_eq!(axis_plane(&p), Some((0, true, 4.0)));
        let oblique = ClipPlane {
            normal: [1.0, 1.0, 0.0],
            offset_mm: 0.0,
        };
        assert_eq!(axis_plane(&oblique), None);
    }
}
