//! The viewer's modality, contrast and preset menus (issue 28, item 5), as a person (or CI)
//! uses them: a scripted offscreen session on a T1 phantom changes the contrast, the preset and
//! the modality (the script steps the menus share); each change opens the volume again through
//! the command line's path, and the log's identity line (the status bar's text) names the new
//! value with its basis `given`. Validation layer required; fails (never skips) without a
//! Vulkan device.

mod common;

use morphray::volume::nifti::write_nifti1;
use morphray::volume::phantom::{PhantomSpec, generate};

#[test]
fn the_menus_steps_open_the_volume_again_as_the_given_contrast_preset_and_modality() {
    let dir = std::env::temp_dir().join(format!("morphray-videntity-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let spec = PhantomSpec {
        dims: [40, 40, 32],
        ..PhantomSpec::cohort_a()
    };
    let volume = dir.join("phantom_T1w.nii.gz");
    write_nifti1(&generate(&spec).unwrap().volume, &volume, true).unwrap();
    let script = [
        "wait 1",
        "contrast t2",
        "wait 2",
        "preset angio",
        "wait 2",
        "modality ct",
        "wait 2",
        "contrast auto",
        "preset auto",
        "modality auto",
        "wait 2",
    ]
    .join("\n");
    let log = common::viewer::offscreen(&volume, &dir, "640x400", &script);
    let identities: Vec<&str> = log.lines().filter(|l| l.starts_with("identity:")).collect();
    println!("{}", identities.join("\n"));
    let first = identities.first().copied().unwrap_or_default();
    assert!(
        first.contains("contrast T1 (metadata)") && first.contains("preset mr"),
        "the file says T1w:\n{log}"
    );
    let seen = |needle: &str| identities.iter().any(|l| l.contains(needle));
    assert!(seen("contrast T2 (given)"), "contrast t2:\n{log}");
    assert!(seen("preset angio"), "preset angio:\n{log}");
    assert!(seen("modality CT (given)"), "modality ct:\n{log}");
    // Back to auto: the last volume shown is read as the file says again.
    let last = identities.last().copied().unwrap_or_default();
    assert!(
        last.contains("contrast T1 (metadata)") && last.contains("preset mr"),
        "after auto:\n{log}"
    );
    assert!(identities.len() >= 4, "one load per change:\n{log}");
    // Each preset's look reaches the picture, as `render` draws it: the angiogram's bright
    // band and vessel channel, the CT's bone and vessel bands, the tissues again at the end.
    let looks: Vec<&str> = log.lines().filter(|l| l.starts_with("look:")).collect();
    println!("{}", looks.join("\n"));
    assert!(
        looks
            .iter()
            .any(|l| l.contains("preset angio: shows pathology; vessels on")),
        "{log}"
    );
    assert!(
        looks
            .iter()
            .any(|l| l.contains("preset ct: shows wm, pathology")),
        "{log}"
    );
    assert!(
        looks
            .last()
            .is_some_and(|l| l.contains("preset mr: shows csf, gm, wm; vessels off")),
        "{log}"
    );
}
