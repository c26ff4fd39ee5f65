//! A profile the daemon cannot use stops it at start, before it serves any
//! vessel, with the file and the profile's key in its message.

use std::process::Command;

#[test]
fn twind_refuses_to_start_on_a_bad_profile_naming_the_key() {
    let dir = std::env::temp_dir().join(format!("twind-bad-profile-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let cases = [
        ("mass_kg = 80.0", "mass_kg = -80.0", "mass.mass_kg"),
        (
            "lateral_offset_m = 0.395",
            "lateral_offset_m = 0.0",
            "propellers.lateral_offset_m",
        ),
        ("[gnss]\n", "[gnss]\nheight_m = 2.0\n", "height_m"),
        ("sway_n_per_mps = 162.5\n", "", "sway_n_per_mps"),
    ];
    for (from, to, key) in cases {
        let profile = twin_wire::profile::OTTER_PROFILE_TOML
            .replace("name = \"otter\"", "name = \"bad\"")
            .replacen(from, to, 1);
        assert_ne!(profile, twin_wire::profile::OTTER_PROFILE_TOML);
        std::fs::write(dir.join("bad.toml"), &profile).unwrap();
        std::fs::write(
            dir.join("twind.toml"),
            "[profiles]\nfiles = [\"bad.toml\"]\ndefault = \"bad\"\n",
        )
        .unwrap();
        let out = Command::new(env!("CARGO_BIN_EXE_twind"))
            .arg("--settings")
            .arg(dir.join("twind.toml"))
            .arg("--no-web")
            .output()
            .unwrap();
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert!(!out.status.success(), "{key}: started");
        assert!(
            stderr.contains("profiles.files")
                && stderr.contains("bad.toml")
                && stderr.contains(key),
            "{key}: {stderr}"
        );
    }
    let _ = std::fs::remove_dir_all(&dir);
}
