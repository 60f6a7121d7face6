//! `--crop`, `--clip-plane` and `--colormap`: the scene options of issue 16 items 2 and 4,
//! flattened into every command's scene arguments (render, view, bench, ...).
//!
//! Decisions: values are checked by the parsers, so a bad crop or plane is a usage error (exit 2)
//! naming the option before any file is read; the library checks the same rules again
//! (`Clip::check`) for clients that do not come through the command line.

use crate::scene::{Clip, ClipPlane, Colormap, Cutaway};
use clap::Args;

/// Crop, clip planes and colour map.
#[derive(Debug, Clone, Default, Args, serde::Serialize)]
#[command(next_help_heading = "Scene")]
pub struct ClipArgs {
    /// Keep part of the volume: fractions 0..1 along the voxel axes i, j, k
    ///
    /// `--crop 0:1,0:1,0.5:1` keeps the upper half of k. Rays start and end exactly on the box.
    #[arg(long, value_name = "X0:X1,Y0:Y1,Z0:Z1", value_parser = parse_crop)]
    pub crop: Option<[[f64; 2]; 3]>,
    /// Cut with a plane in world mm, keeping NX*x + NY*y + NZ*z + D >= 0; repeatable, up to 4
    ///
    /// The kept side is the one the normal points to.
    /// `--clip-plane -1,0,0,0` keeps x <= 0: the patient's left half in RAS+ (+x = right).
    #[arg(long = "clip-plane", value_name = "NX,NY,NZ,D", value_parser = parse_plane, allow_hyphen_values = true)]
    pub clip_plane: Vec<ClipPlane>,
    /// Colour map of MIP/MinIP (default: grey), or of DVR samples instead of the tissue colours.
    ///
    /// In MIP/MinIP the map colours the display window; in DVR each sample's intensity through
    /// the same window, while the tissue windows still decide opacity.
    #[arg(long, value_name = "gray|hot|viridis|inferno|bone", value_parser = parse_colormap)]
    pub colormap: Option<Colormap>,
    /// Open the brain: cut away the side facing the camera, through the centre or X,Y,Z (mm)
    ///
    /// A clip plane through the volume's centre (or the world point X,Y,Z in mm) that turns with
    /// the camera; the cut face is drawn solid in the tissue colours (cortex over white matter,
    /// the ventricles) where eq. 4 alone would show a flat interior see-through. An oblique view
    /// shows it best: `--cutaway --azimuth 40 --elevation 25`; a point is given with `=`:
    /// `--cutaway=-12,4,8`. Takes one of the 4 clip-plane slots.
    #[arg(long, value_name = "X,Y,Z", num_args = 0..=1, default_missing_value = "centre", require_equals = true, value_parser = parse_cutaway)]
    pub cutaway: Option<Cutaway>,
}

impl ClipArgs {
    /// The clip region these options describe.
    pub fn clip(&self) -> Result<Clip, String> {
        let mut clip = Clip::default();
        if let Some(crop) = self.crop {
            clip.crop = crop;
        }
        for plane in &self.clip_plane {
            clip.add_plane(*plane).map_err(|e| e.0)?;
        }
        clip.check().map_err(|e| e.0)?;
        if self.cutaway.is_some() && clip.planes.iter().all(Option::is_some) {
            return Err(format!(
                "--cutaway needs one of the {} clip-plane slots: give at most {} --clip-plane \
                 options with it",
                crate::scene::clip::MAX_CLIP_PLANES,
                crate::scene::clip::MAX_CLIP_PLANES - 1
            ));
        }
        Ok(clip)
    }
}

fn parse_crop(text: &str) -> Result<[[f64; 2]; 3], String> {
    crate::scene::clip::parse_crop(text).map_err(|e| e.0)
}

fn parse_plane(text: &str) -> Result<ClipPlane, String> {
    let values: Vec<f64> = text
        .split(',')
        .map(|v| v.trim().parse::<f64>().ok().filter(|x| x.is_finite()))
        .collect::<Option<_>>()
        .ok_or_else(|| format!("`{text}`: expected four finite numbers NX,NY,NZ,D"))?;
    let [nx, ny, nz, d] = values[..] else {
        return Err(format!("`{text}`: expected four numbers NX,NY,NZ,D"));
    };
    if nx == 0.0 && ny == 0.0 && nz == 0.0 {
        return Err(format!("`{text}`: the normal NX,NY,NZ must not be zero"));
    }
    Ok(ClipPlane {
        normal: [nx, ny, nz],
        offset_mm: d,
    })
}

fn parse_cutaway(text: &str) -> Result<Cutaway, String> {
    if ["centre", "center"].contains(&text.trim()) {
        return Ok(Cutaway::default());
    }
    let values: Vec<f64> = text
        .split(',')
        .map(|v| v.trim().parse::<f64>().ok().filter(|x| x.is_finite()))
        .collect::<Option<_>>()
        .ok_or_else(|| format!("`{text}`: expected `centre` or three finite numbers X,Y,Z (mm)"))?;
    let [x, y, z] = values[..] else {
        return Err(format!("`{text}`: expected three numbers X,Y,Z (world mm)"));
    };
    Ok(Cutaway {
        point_mm: Some([x, y, z]),
    })
}

fn parse_colormap(text: &str) -> Result<Colormap, String> {
    Colormap::parse(text).ok_or_else(|| {
        let names: Vec<&str> = Colormap::ALL.iter().map(|m| m.name()).collect();
        format!("unknown colour map `{text}`; use {}", names.join(", "))
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn crops_planes_and_maps_parse_or_say_why_not() {
        assert_eq!(
            parse_crop("0:1, 0.25:0.75,0.5:1").unwrap(),
            [[0.0, 1.0], [0.25, 0.75], [0.5, 1.0]]
        );
        assert!(parse_crop("0:1,0:1").unwrap_err().contains("three ranges"));
        assert!(
            parse_crop("0:1,0.7:0.2,0:1")
                .unwrap_err()
                .contains("--crop Y")
        );
        assert!(parse_crop("0:1,0:1,0:2").unwrap_err().contains("--crop Z"));
        assert!(
            parse_crop("0:1,a:1,0:1")
                .unwrap_err()
                .contains("not a finite")
        );
        let p = parse_plane("-1, 0, 0, 2.5").unwrap();
        assert_eq!(p.normal, [-1.0, 0.0, 0.0]);
        assert_eq!(p.offset_mm, 2.5);
        assert!(parse_plane("0,0,0,1").unwrap_err().contains("zero"));
        assert!(parse_plane("1,0,0").unwrap_err().contains("four"));
        assert!(parse_plane("1,0,0,inf").is_err());
        assert_eq!(parse_colormap("Viridis").unwrap(), Colormap::Viridis);
        assert!(parse_colormap("jet").unwrap_err().contains("gray, hot"));
        let too_many = ClipArgs {
            clip_plane: vec![p; 5],
            ..ClipArgs::default()
        };
        assert!(too_many.clip().unwrap_err().contains("at most 4"));
    }
}
