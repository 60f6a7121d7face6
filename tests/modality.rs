//! What a volume is, from its metadata first (issue 28, items 1 and 4), on the library: each
//! rule of `analysis::modality` and its basis, the overrides, the decided contrast placing the
//! tissues (T2, PD, FLAIR orders), and the foreground fallback of a scan with one tissue mode.
//! CPU only; the command line and the GPU path are in tests/modality_cli.rs.

use morphray::analysis::{
    self, AnalysisParams, Basis, Contrast, ContrastChoice, Identity, Modality, ModalityChoice,
    ScanFacts, SequenceKind, ValueSummary, identify,
};
use morphray::reference::BINS;

fn id(facts: &ScanFacts) -> Identity {
    identify(facts, None, ModalityChoice::Auto, ContrastChoice::Auto)
}

/// (modality, its basis, contrast and its basis; None = left to the histogram).
fn outcome(facts: &ScanFacts) -> (Modality, Basis, Option<(Contrast, Basis)>) {
    let i = id(facts);
    let c = i.contrast.as_ref().map(|c| (c.contrast, c.basis));
    (i.modality.modality, i.modality.basis, c)
}

fn suffix(s: &str) -> ScanFacts {
    ScanFacts {
        bids_suffix: Some(s.into()),
        ..Default::default()
    }
}

fn described(text: &str) -> ScanFacts {
    ScanFacts {
        series_description: Some(text.into()),
        ..Default::default()
    }
}

fn timed(tr: Option<f64>, te: Option<f64>, ti: Option<f64>) -> ScanFacts {
    ScanFacts {
        repetition_time_ms: tr,
        echo_time_ms: te,
        inversion_time_ms: ti,
        ..Default::default()
    }
}

const META: Basis = Basis::Metadata;

#[test]
fn bids_suffixes_name_the_contrast_and_the_kind() {
    let mr = |c| (Modality::Mr, META, Some((c, META)));
    assert_eq!(outcome(&suffix("T1w")), mr(Contrast::T1));
    assert_eq!(outcome(&suffix("T2w")), mr(Contrast::T2));
    assert_eq!(outcome(&suffix("PDw")), mr(Contrast::Pd));
    assert_eq!(outcome(&suffix("FLAIR")), mr(Contrast::Flair));
    assert_eq!(outcome(&suffix("angio")), mr(Contrast::T1));
    assert_eq!(id(&suffix("angio")).kind, Some(SequenceKind::Angio));
    assert_eq!(id(&suffix("bold")).kind, Some(SequenceKind::Bold));
    assert_eq!(outcome(&suffix("bold")), mr(Contrast::T2));
    assert_eq!(outcome(&suffix("asl")), mr(Contrast::Pd));
    assert_eq!(outcome(&suffix("dwi")), mr(Contrast::T2));
    assert_eq!(
        outcome(&suffix("ct")),
        (Modality::Ct, META, Some((Contrast::Ct, META)))
    );
    // An unknown suffix says nothing.
    assert_eq!(
        outcome(&suffix("AVM")),
        (Modality::Mr, Basis::Assumed, None)
    );
    assert_eq!(
        id(&suffix("T2w")).contrast.unwrap().reason,
        "BIDS suffix _T2w"
    );
}

#[test]
fn description_words_name_the_contrast_before_the_timing() {
    let c = |f: &ScanFacts| id(f).contrast.map(|c| c.contrast);
    assert_eq!(c(&described("AX T2 FLAIR")), Some(Contrast::Flair));
    assert_eq!(c(&described("t1_mprage_sag_p2")), Some(Contrast::T1));
    assert_eq!(c(&described("MP-RAGE")), Some(Contrast::T1));
    assert_eq!(c(&described("PD_TSE_cor")), Some(Contrast::Pd));
    assert_eq!(c(&described("Sag T1 FLAIR")), Some(Contrast::T1));
    assert_eq!(c(&described("ax tse")), Some(Contrast::T2));
    assert_eq!(c(&described("TOF_3D_multi-slab")), Some(Contrast::T1));
    assert_eq!(id(&described("TOF_3D")).kind, Some(SequenceKind::Angio));
    assert_eq!(id(&described("SWI_Images")).kind, Some(SequenceKind::Swi));
    // ProtocolName and descrip speak too; the reason names the field and the word.
    let p = ScanFacts {
        protocol_name: Some("T2W_TSE".into()),
        ..Default::default()
    };
    let r = id(&p).contrast.unwrap();
    assert_eq!((r.contrast, r.basis), (Contrast::T2, META));
    assert!(
        r.reason.contains("ProtocolName") && r.reason.contains("T2W"),
        "{}",
        r.reason
    );
    // A named T1 whose timing says T2: the name wins, the reason says both.
    let mut both = described("T1 axial");
    both.repetition_time_ms = Some(4000.0);
    both.echo_time_ms = Some(100.0);
    let r = id(&both).contrast.unwrap();
    assert_eq!(r.contrast, Contrast::T1);
    assert!(r.reason.contains("would say T2"), "{}", r.reason);
}

#[test]
fn timing_decides_when_no_word_does() {
    let c = |tr, te, ti| {
        id(&timed(tr, te, ti))
            .contrast
            .map(|c| (c.contrast, c.basis))
    };
    assert_eq!(
        c(Some(9000.0), Some(120.0), Some(2500.0)),
        Some((Contrast::Flair, META))
    );
    assert_eq!(
        c(Some(4000.0), Some(100.0), None),
        Some((Contrast::T2, META))
    );
    assert_eq!(c(Some(500.0), Some(12.0), None), Some((Contrast::T1, META)));
    assert_eq!(
        c(Some(3000.0), Some(15.0), None),
        Some((Contrast::Pd, META))
    );
    assert_eq!(
        c(Some(2300.0), Some(2.3), Some(900.0)),
        Some((Contrast::T1, META))
    );
    // Times alone also say MR.
    let i = id(&timed(Some(4000.0), Some(100.0), None));
    assert_eq!(
        (i.modality.modality, i.modality.basis),
        (Modality::Mr, META)
    );
    assert!(i.contrast.unwrap().reason.contains("TE 100 ms"));
}

#[test]
fn the_modality_tag_and_hounsfield_values_name_a_ct() {
    let tag = |t: &str| ScanFacts {
        modality: Some(t.into()),
        ..Default::default()
    };
    assert_eq!(
        outcome(&tag("CT")),
        (Modality::Ct, META, Some((Contrast::Ct, META)))
    );
    assert_eq!(outcome(&tag("PT")), (Modality::Pt, META, None));
    assert_eq!(outcome(&tag("US")).0, Modality::Other);
    // No metadata: air at -1000 HU, brain near 40, bone at 1000: CT from the values.
    let hu = ValueSummary::of((0..10_000).map(|i| match i % 10 {
        0..=3 => -1000.0,
        4..=8 => 40.0,
        _ => 1000.0,
    }));
    let i = identify(
        &ScanFacts::default(),
        Some(&hu),
        ModalityChoice::Auto,
        ContrastChoice::Auto,
    );
    assert_eq!(
        (i.modality.modality, i.modality.basis),
        (Modality::Ct, Basis::Values)
    );
    assert_eq!(
        i.contrast.map(|c| (c.contrast, c.basis)),
        Some((Contrast::Ct, Basis::Values))
    );
    // A CT by name whose values are not HU keeps its name, and the reason says so.
    let named = ScanFacts {
        file_name: Some("CT_AVM".into()),
        ..Default::default()
    };
    let bytes = ValueSummary::of((0..1000).map(|i| f64::from(i % 256)));
    let i = identify(
        &named,
        Some(&bytes),
        ModalityChoice::Auto,
        ContrastChoice::Auto,
    );
    assert_eq!(
        (i.modality.modality, i.modality.basis),
        (Modality::Ct, META)
    );
    assert!(
        i.modality.reason.contains("not Hounsfield"),
        "{}",
        i.modality.reason
    );
    // MR magnitudes with no metadata: MR assumed, the contrast left to the histogram.
    let mr = ValueSummary::of((0..1000).map(f64::from));
    let i = identify(
        &ScanFacts::default(),
        Some(&mr),
        ModalityChoice::Auto,
        ContrastChoice::Auto,
    );
    assert_eq!(
        (i.modality.modality, i.modality.basis),
        (Modality::Mr, Basis::Assumed)
    );
    assert_eq!(i.contrast, None);
}

#[test]
fn contrast_agents_flag_a_post_contrast_scan() {
    let mut f = suffix("T1w");
    assert!(!id(&f).post_contrast);
    f.bids_ce = Some("gadolinium".into());
    assert!(id(&f).post_contrast);
    let agent = ScanFacts {
        contrast_agent: Some("GADAVIST 10 ML".into()),
        ..described("T1 SE")
    };
    assert!(id(&agent).post_contrast);
    assert!(id(&described("T1 MPRAGE post Gd")).post_contrast);
    assert!(!id(&described("T1 MPRAGE pre")).post_contrast);
    let none = ScanFacts {
        contrast_agent: Some("None".into()),
        ..described("T1 SE")
    };
    assert!(!id(&none).post_contrast);
    let report = id(&agent).contrast_or_else(|| unreachable!());
    assert!(report.post_contrast && report.summary().starts_with("T1 post-contrast (metadata)"));
}

#[test]
fn overrides_win_over_everything_and_say_given() {
    let f = ScanFacts {
        modality: Some("MR".into()),
        ..suffix("T1w")
    };
    let i = identify(
        &f,
        None,
        ModalityChoice::Given(Modality::Ct),
        ContrastChoice::Flair,
    );
    assert_eq!(
        (i.modality.modality, i.modality.basis),
        (Modality::Ct, Basis::Given)
    );
    let c = i.contrast.unwrap();
    assert_eq!((c.contrast, c.basis), (Contrast::Flair, Basis::Given));
    assert!(c.reason.starts_with("--contrast flair"), "{}", c.reason);
    // --modality ct alone makes the contrast CT's density order.
    let i = identify(
        &f,
        None,
        ModalityChoice::Given(Modality::Ct),
        ContrastChoice::Auto,
    );
    assert_eq!(
        i.contrast.map(|c| (c.contrast, c.basis)),
        Some((Contrast::Ct, Basis::Given))
    );
}

/// A histogram of Gaussians `(centre I_norm, sd I_norm, voxels)`.
fn histogram(parts: &[(f64, f64, f64)]) -> [u32; BINS] {
    let mut h = [0u32; BINS];
    for (b, count) in h.iter_mut().enumerate() {
        let x = (b as f64 + 0.5) / BINS as f64;
        let v: f64 = parts
            .iter()
            .map(|&(c, sd, n)| {
                n / (sd * BINS as f64 * (2.0 * std::f64::consts::PI).sqrt())
                    * (-0.5 * ((x - c) / sd).powi(2)).exp()
            })
            .sum();
        *count = v.round() as u32;
    }
    h
}

fn analyze_as(h: &[u32; BINS], contrast: ContrastChoice) -> analysis::TissueReport {
    let total = h.iter().map(|&c| c as usize).sum();
    let identity = Identity::from_choices(ModalityChoice::Auto, contrast);
    let params = AnalysisParams::default();
    analysis::analyze_identified(h, 0.0, 1000.0, total, 0, &params, &identity)
}

fn near(p: Option<analysis::Peak>, x: f64) -> bool {
    p.is_some_and(|p| (p.norm - x).abs() < 0.02)
}

#[test]
fn the_decided_contrast_orders_the_tissues() {
    // Air, then three tissue modes.
    let air = (0.02, 0.01, 400_000.0);
    // T2: WM 0.25 (large, sharp), GM 0.35, CSF 0.8 (broad).
    let t2 = histogram(&[
        air,
        (0.25, 0.02, 300_000.0),
        (0.35, 0.025, 250_000.0),
        (0.8, 0.05, 120_000.0),
    ]);
    let r = analyze_as(&t2, ContrastChoice::T2);
    assert!(
        near(r.peaks.wm, 0.25) && near(r.peaks.gm, 0.35) && near(r.peaks.csf, 0.8),
        "{:?}",
        r.peaks
    );
    // PD: WM 0.5, GM 0.58, CSF 0.72 (1.45 x WM): CSF is found at PD's lower ratio.
    let pd = histogram(&[
        air,
        (0.5, 0.015, 300_000.0),
        (0.58, 0.015, 250_000.0),
        (0.72, 0.02, 100_000.0),
    ]);
    let r = analyze_as(&pd, ContrastChoice::Pd);
    assert!(
        near(r.peaks.wm, 0.5) && near(r.peaks.gm, 0.58) && near(r.peaks.csf, 0.72),
        "{:?}",
        r.peaks
    );
    assert_eq!(r.contrast.contrast, Contrast::Pd);
    // FLAIR: CSF dark (0.15), WM 0.55, GM 0.7 the brightest large class.
    let flair = histogram(&[
        air,
        (0.15, 0.03, 80_000.0),
        (0.55, 0.03, 300_000.0),
        (0.7, 0.03, 280_000.0),
    ]);
    let r = analyze_as(&flair, ContrastChoice::Flair);
    assert!(
        near(r.peaks.csf, 0.15) && near(r.peaks.wm, 0.55) && near(r.peaks.gm, 0.7),
        "{:?}",
        r.peaks
    );
    // The same FLAIR histogram read as T1 swaps GM and WM: the metadata matters.
    let r = analyze_as(&flair, ContrastChoice::T1);
    assert!(
        near(r.peaks.wm, 0.7) && near(r.peaks.gm, 0.55),
        "{:?}",
        r.peaks
    );
    // Windows follow the order: FLAIR's GM window lies above its WM window.
    let r = analyze_as(&flair, ContrastChoice::Flair);
    let (gm, wm) = (
        r.adaptive_windows.gm.unwrap(),
        r.adaptive_windows.wm.unwrap(),
    );
    assert!(gm.lo >= wm.hi - 1e-12, "{gm:?} {wm:?}");
}

#[test]
fn one_tissue_mode_above_the_background_falls_back_to_the_foreground() {
    // Air noise and a single broad tissue mode (the clinical T2 head of issue 28).
    let h = histogram(&[(0.03, 0.012, 600_000.0), (0.45, 0.12, 400_000.0)]);
    let r = analyze_as(&h, ContrastChoice::Auto);
    assert_eq!(r.peaks, analysis::Peaks::default(), "{:?}", r.modes);
    let f = r.fallback.clone().expect("a foreground window");
    assert!(f.reason.contains("no tissue class"), "{}", f.reason);
    let wm = r.adaptive_windows.wm.expect("shown in the WM slot");
    assert_eq!(wm, f.window);
    // Background voxels get weight 0, the tissue full weight.
    assert_eq!(wm.weight(0.03), 0.0);
    assert_eq!(wm.weight(0.45), 1.0);
    assert!(wm.lo > r.background_threshold && wm.lo < 0.2, "{wm:?}");
    // No background (a ramp), nothing at all, or tissue classes found: no fallback.
    let ramp = analyze_as(&[1000; BINS], ContrastChoice::Auto);
    assert_eq!(ramp.fallback, None);
    assert_eq!(analyze_as(&[0; BINS], ContrastChoice::Auto).fallback, None);
    let t1 = histogram(&[
        (0.03, 0.012, 600_000.0),
        (0.3, 0.03, 80_000.0),
        (0.6, 0.03, 300_000.0),
        (0.8, 0.02, 300_000.0),
    ]);
    let r = analyze_as(&t1, ContrastChoice::Auto);
    assert!(
        r.peaks.wm.is_some() && r.fallback.is_none(),
        "{:?}",
        r.peaks
    );
}
