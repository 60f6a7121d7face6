//! A cache folder that cannot take files (issue 30 item 7): a file in its place, a folder where
//! no file can be created. Both the driver's shader cache (Mesa's, turned off through its
//! variables before the Vulkan instance exists) and morphray's pipeline cache are turned off
//! with one line each, and the render goes on.

use std::process::Command;

fn render(cache_home: &str, out: &std::path::Path) -> (bool, String) {
    let o = Command::new(env!("CARGO_BIN_EXE_morphray"))
        .args(["render", "-o", out.to_str().unwrap(), "--size", "32x32"])
        .env("XDG_CACHE_HOME", cache_home)
        .env_remove("MORPHRAY_CACHE_DIR")
        .env_remove("MESA_SHADER_CACHE_DIR")
        .env_remove("MESA_SHADER_CACHE_DISABLE")
        .output()
        .expect("the morphray binary runs");
    (
        o.status.success(),
        String::from_utf8_lossy(&o.stderr).into_owned(),
    )
}

#[test]
fn a_file_or_a_folder_without_room_is_turned_off_with_one_line_each() {
    let root = std::env::temp_dir().join(format!("morphray-cache-off-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&root);
    std::fs::create_dir_all(&root).unwrap();
    let file = root.join("cache-file");
    std::fs::write(&file, b"not a folder").unwrap();
    // /proc takes no new file, even for root (a chmod-ed folder does not stop root).
    for (home, why) in [
        (file.to_str().unwrap(), "is a file, not a folder"),
        ("/proc/self/none", "no file can be created in /proc/self"),
    ] {
        let out = root.join("out.png");
        let (ok, said) = render(home, &out);
        assert!(ok, "{said}");
        assert!(out.is_file());
        let lines: Vec<&str> = said
            .lines()
            .filter(|l| l.starts_with("morphray:") && l.contains(why))
            .collect();
        assert_eq!(lines.len(), 2, "one line per cache: {said}");
        assert!(lines[0].contains("shader cache is off"), "{said}");
        assert!(
            lines[1].contains("pipeline cache is kept in memory"),
            "{said}"
        );
        assert!(
            !said.contains("os error 17") && !said.contains("cannot write the pipeline"),
            "{said}"
        );
        std::fs::remove_file(&out).unwrap();
    }
    std::fs::remove_dir_all(&root).unwrap();
}
