//! The classification as a 1-D transfer-function table (issue 33 item 1): the per-sample loop
//! over the tissue windows (two smoothsteps each, plus the head layer's) replaced by one linear
//! lookup in a table built on the host when the classification changes.
//!
//! Decisions:
//! - **What the table holds**: the opacity-weighted sums before they are mixed, per I_norm value
//!   `v_i = i / (N - 1)`: `(sum_t w_t(v) op_t c_t, sum_t w_t(v) op_t)` over the visible tissues
//!   (entries `0..N`), and the head layer's term (entries `N..2N`). The brain mask, the vessel
//!   channel, the division by the total and the clamp of f to 1 stay per sample, so the table
//!   depends on the classification only, and every channel keeps the exact rule of
//!   `Classification::classify_masked`; only the windows are interpolated.
//! - **N = 4096 entries, linear interpolation**: for a window edge half-width `e` the
//!   smoothstep's second derivative is at most `1.5 / e^2`, so linear interpolation between
//!   entries `h = 1/4095` apart errs by at most `h^2 / 8 * 1.5 / e^2`: 1.1e-4 of the weight at
//!   `e = 0.01` (the hand-set edge, `MANUAL_EDGE`), less at the adaptive windows' wider edges.
//!   At the renderer's 16-bit I_norm the texture itself resolves 1/65535.
//! - **f32 entries**, as the GPU reads them; the f64 twin ([`TransferTable::classify_masked`])
//!   interpolates those same f32 values in f64, so GPU-vs-twin differences are the shader's f32
//!   arithmetic only, and twin-vs-exact differences are the table's (measured by the accuracy
//!   study's "classification table" setting).
//! - The GPU buffer is `2 N` RGBA32F texels (128 KiB) read with `texelFetch` from a uniform
//!   texel buffer (a storage-buffer read at a per-sample index runs lane by lane on CPU devices:
//!   BENCHMARKS.md "Per-sample tables as texel buffers"), rewritten per frame slot only when the
//!   classification changed (engine/transfer.rs).

use super::classification::{Classification, render_weight};

/// Entries per half of the table (tissues, head layer).
pub const TABLE_ENTRIES: usize = 4096;

/// The I_norm distance between neighbouring entries.
pub const ENTRY_SPACING: f64 = 1.0 / (TABLE_ENTRIES - 1) as f64;

/// Bytes of the GPU table: two halves of `vec4`s.
pub const TABLE_BYTES: u64 = (2 * TABLE_ENTRIES * 16) as u64;

/// The classification sampled at `TABLE_ENTRIES` I_norm values, as uploaded.
#[derive(Clone, Debug, PartialEq)]
pub struct TransferTable {
    /// `2 * TABLE_ENTRIES` entries: tissue sums, then the head layer's term; each
    /// (opacity-weighted rgb sum, opacity-weighted weight sum).
    pub entries: Vec<[f32; 4]>,
}

impl TransferTable {
    /// The table of `classification` (invisible tissues, tissues without a window and a hidden
    /// head layer contribute zeros, as in `Classification::classify_masked`).
    pub fn new(classification: &Classification) -> Self {
        let mut entries = vec![[0.0f32; 4]; 2 * TABLE_ENTRIES];
        for (i, entry) in entries[..TABLE_ENTRIES].iter_mut().enumerate() {
            let v = i as f64 / (TABLE_ENTRIES - 1) as f64;
            let mut sums = [0.0f64; 4];
            for style in &classification.tissues {
                let Some(window) = style.window.filter(|_| style.visible) else {
                    continue;
                };
                let w = render_weight(&window, v) * style.opacity.clamp(0.0, 1.0) as f64;
                add_term(&mut sums, w, style.colour);
            }
            *entry = sums.map(|s| s as f32);
        }
        let head = &classification.head;
        if head.visible {
            for (i, entry) in entries[TABLE_ENTRIES..].iter_mut().enumerate() {
                let v = i as f64 / (TABLE_ENTRIES - 1) as f64;
                let mut sums = [0.0f64; 4];
                let w = render_weight(&head.window, v) * head.opacity.clamp(0.0, 1.0) as f64;
                add_term(&mut sums, w, head.colour);
                *entry = sums.map(|s| s as f32);
            }
        }
        TransferTable { entries }
    }

    /// The table's bytes as the shader reads them (RGBA32F texels).
    pub fn bytes(&self) -> &[u8] {
        bytemuck::cast_slice(&self.entries)
    }

    /// One half's entry at `v` by linear interpolation, exactly the shader's lookup rule
    /// (`classification.glsl`, `table_sums`): `x = clamp(v, 0, 1) (N - 1)`, `i = min(floor x,
    /// N - 2)`, `mix(T[i], T[i + 1], x - i)`, in f64 over the f32 entries.
    pub fn lookup(&self, half: usize, v: f64) -> [f64; 4] {
        let x = v.clamp(0.0, 1.0) * (TABLE_ENTRIES - 1) as f64;
        let i = (x.floor() as usize).min(TABLE_ENTRIES - 2);
        let f = x - i as f64;
        let base = half * TABLE_ENTRIES + i;
        let (a, b) = (self.entries[base], self.entries[base + 1]);
        std::array::from_fn(|c| a[c] as f64 + f * (b[c] as f64 - a[c] as f64))
    }

    /// `Classification::classify_masked` with the tissue and head windows read from the table
    /// (the twin of `classify_sums` with CLASSIFY_TABLE); `classification` supplies the vessel
    /// channel, which stays exact.
    pub fn classify_masked(
        &self,
        classification: &Classification,
        v: f64,
        vesselness: Option<f64>,
        brain: Option<f64>,
    ) -> (f64, [f64; 3]) {
        let b = brain.map_or(1.0, |b| b.clamp(0.0, 1.0));
        let mut sums = [0.0f64; 4];
        if let Some(vesselness) = vesselness {
            let style = &classification.vessels;
            let w = render_weight(&style.window, vesselness) * style.opacity.clamp(0.0, 1.0) as f64;
            add_term(&mut sums, w, style.colour);
        }
        let tissue = self.lookup(0, v);
        for (s, t) in sums.iter_mut().zip(tissue) {
            *s += b * t;
        }
        if brain.is_some() {
            let head = self.lookup(1, v);
            for (s, h) in sums.iter_mut().zip(head) {
                *s += (1.0 - b) * h;
            }
        }
        let total = sums[3];
        if total <= 0.0 {
            return (0.0, [0.0; 3]);
        }
        (
            total.min(1.0),
            [sums[0] / total, sums[1] / total, sums[2] / total],
        )
    }
}

fn add_term(sums: &mut [f64; 4], w: f64, colour: [f32; 3]) {
    for (s, c) in sums.iter_mut().zip(colour) {
        *s += w * c as f64;
    }
    sums[3] += w;
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::classification::{TissueClass, Window};

    fn scene_classification() -> Classification {
        let w = |lo, hi, edge| Some(Window { lo, hi, edge });
        let mut c = Classification::with_windows([
            w(0.1, 0.3, 0.02),
            w(0.35, 0.6, 0.03),
            w(0.62, 0.9, 0.04),
            w(0.93, 1.2, 0.01),
        ]);
        c.style_mut(TissueClass::Pathology).visible = true;
        c.head.visible = true;
        c
    }

    #[test]
    fn the_table_is_the_classification_within_its_interpolation_bound() {
        let c = scene_classification();
        let table = TransferTable::new(&c);
        // Awkward positions between entries, the edges and beyond [0, 1].
        let mut worst = 0.0f64;
        for k in 0..=20011 {
            let v = -0.01 + 1.02 * k as f64 / 20011.0;
            for brain in [None, Some(0.0), Some(0.37), Some(1.0)] {
                let (f, colour) = c.classify_masked(v, None, brain);
                let (g, table_colour) = table.classify_masked(&c, v, None, brain);
                worst = worst.max((f - g).abs());
                if f > 0.05 {
                    for (a, b) in colour.iter().zip(table_colour) {
                        assert!((a - b).abs() < 5e-3, "colour at v {v}: {a} vs {b}");
                    }
                }
            }
        }
        // Edge 0.01 at entries 1/4095 apart: h^2/8 * 1.5/e^2 = 1.1e-4 (module docs), plus f32.
        assert!(worst < 1.5e-4, "worst |f - f_table| {worst}");
        assert!(
            worst > 0.0,
            "the table interpolates: it cannot be exact everywhere"
        );
    }

    #[test]
    fn hidden_layers_and_tissues_are_zero_in_the_table() {
        let mut c = scene_classification();
        c.head.visible = false;
        c.show_only(&[TissueClass::Wm]);
        let table = TransferTable::new(&c);
        assert!(
            table.entries[TABLE_ENTRIES..]
                .iter()
                .all(|e| *e == [0.0; 4])
        );
        // CSF's window (0.1..0.3) is hidden: nothing there.
        assert_eq!(table.lookup(0, 0.2), [0.0; 4]);
        assert!(table.lookup(0, 0.75)[3] > 0.8);
        assert_eq!(table.bytes().len() as u64, TABLE_BYTES);
    }

    #[test]
    fn the_vessel_channel_stays_exact() {
        let c = scene_classification();
        let table = TransferTable::new(&c);
        // At a v where no tissue is drawn the table adds nothing: the vessel term alone.
        let v = 0.005;
        let exact = c.classify_with_vessels(v, Some(0.7));
        let tabled = table.classify_masked(&c, v, Some(0.7), None);
        assert!((exact.0 - tabled.0).abs() < 1e-12);
    }
}
