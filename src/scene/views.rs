//! The six standard views (anterior, posterior, left, right, superior, inferior): one table for
//! the viewer's buttons and keys, its scripts and the command line's `--view`.
//!
//! Decision: the superior and inferior views show anterior at the top, as radiologists and every
//! clinical viewer do (issue 16). The camera's up vector at a pole is the limit of the orbit
//! (`camera.rs`), so the superior view is reached from behind (azimuth 180) and the inferior
//! from the front (azimuth 0): both put anterior up, and no drag away from them flips the image.

/// The six standard views, named for where the camera looks from.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum StandardView {
    /// From the front (the face): patient's left on the image's right.
    Anterior,
    /// From behind.
    Posterior,
    /// From the patient's left side.
    Left,
    /// From the patient's right side.
    Right,
    /// From above (the vertex).
    Superior,
    /// From below.
    Inferior,
}

impl StandardView {
    /// All six, in the order of the interface's buttons.
    pub const ALL: [StandardView; 6] = [
        StandardView::Anterior,
        StandardView::Posterior,
        StandardView::Left,
        StandardView::Right,
        StandardView::Superior,
        StandardView::Inferior,
    ];

    /// Lower-case name (`anterior`, ...), as in scripts.
    pub fn name(self) -> &'static str {
        match self {
            StandardView::Anterior => "anterior",
            StandardView::Posterior => "posterior",
            StandardView::Left => "left",
            StandardView::Right => "right",
            StandardView::Superior => "superior",
            StandardView::Inferior => "inferior",
        }
    }

    /// Parses a name or its first letter (`a`, `anterior`, ...).
    pub fn parse(text: &str) -> Option<StandardView> {
        let t = text.trim().to_lowercase();
        StandardView::ALL
            .into_iter()
            .find(|v| v.name() == t || (t.len() == 1 && v.name().starts_with(&t)))
    }

    /// The key that selects it (its initial: A, P, L, R, S, I).
    pub fn letter(self) -> char {
        match self {
            StandardView::Anterior => 'A',
            StandardView::Posterior => 'P',
            StandardView::Left => 'L',
            StandardView::Right => 'R',
            StandardView::Superior => 'S',
            StandardView::Inferior => 'I',
        }
    }

    /// Azimuth and elevation in degrees (see `camera.rs`: azimuth 90 = from the right).
    pub fn angles(self) -> (f64, f64) {
        match self {
            StandardView::Anterior => (0.0, 0.0),
            StandardView::Posterior => (180.0, 0.0),
            StandardView::Left => (-90.0, 0.0),
            StandardView::Right => (90.0, 0.0),
            // Reached from behind (azimuth 180): anterior at the top, and the orbit's limit at the
            // pole (scene/camera.rs), so dragging away from it never flips the image.
            StandardView::Superior => (180.0, 90.0),
            // Reached from the front: anterior at the top here too.
            StandardView::Inferior => (0.0, -90.0),
        }
    }
}
