//! The memory plan against the measured peak: bakes of about a million texels (the Cornell
//! box, and the house of the corpus), each run in a child process so that its peak resident
//! memory (`VmHWM`) is its own, peak within 15% of what the plan admitted them with.

use std::path::Path;
use std::process::Command;

use lightbake::progress::Progress;
use lightbake::scene::testscenes::{CornellLight, cornell_box};
use lightbake::settings::{BakeSettings, LightConvention};

/// The child's variable: which scene to bake.
const CASE: &str = "LIGHTBAKE_MEMORY_CASE";

/// In the child: bakes `case` at about a million texels and prints its plan and peak.
fn child(case: &str) {
    let scene = match case {
        "house" => {
            let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../assets/corpus/house.gltf");
            lightbake::import_gltf(&path, LightConvention::GltfSpec)
                .unwrap()
                .scene
        }
        _ => cornell_box(CornellLight::Area),
    };
    let mut s = BakeSettings::preview();
    s.layout.texel_density_from_scene = false;
    s.layout.texel_budget = 1 << 20;
    let out = lightbake::bake(&scene, &s, &Progress::new()).unwrap();
    let radiosity = out.report.radiosity.as_ref().unwrap();
    let planned = out.report.memory.total
        + radiosity.transport_estimate_bytes
        + radiosity.solver_working_bytes;
    println!(
        "MEMORY {case} patches {} planned {planned} peak {}",
        out.report.texels.patches,
        lightbake::memory::peak_resident_bytes().expect("VmHWM in /proc/self/status")
    );
}

#[test]
fn the_memory_plan_is_within_15_percent_of_the_peak_at_a_million_texels() {
    if let Ok(case) = std::env::var(CASE) {
        child(&case);
        return;
    }
    let exe = std::env::current_exe().unwrap();
    for case in ["cornell", "house"] {
        let out = Command::new(&exe)
            .args([
                "--exact",
                "the_memory_plan_is_within_15_percent_of_the_peak_at_a_million_texels",
                "--nocapture",
                "--test-threads=1",
            ])
            .env(CASE, case)
            .output()
            .unwrap();
        let stdout = String::from_utf8_lossy(&out.stdout);
        assert!(
            out.status.success(),
            "{case}: {stdout}{}",
            String::from_utf8_lossy(&out.stderr)
        );
        // The harness may print "test … " on the same line before the child's report.
        let line = stdout
            .lines()
            .find_map(|l| l.find("MEMORY ").map(|at| &l[at..]))
            .unwrap_or_else(|| panic!("{case}: no report in {stdout}"));
        let words: Vec<&str> = line.split_whitespace().collect();
        let number = |key: &str| -> f64 {
            let k = words.iter().position(|w| *w == key).expect(key);
            words[k + 1].parse().expect(key)
        };
        let (patches, planned, peak) = (number("patches"), number("planned"), number("peak"));
        let ratio = planned / peak;
        println!(
            "{case}: {patches} patches, planned {:.0} MiB, peak {:.0} MiB ({:.0} bytes per patch), plan / peak {ratio:.3}",
            planned / 1048576.0,
            peak / 1048576.0,
            peak / patches
        );
        assert!(patches > 900_000.0, "{case}: {patches} patches");
        assert!(
            (0.85..=1.15).contains(&ratio),
            "{case}: planned {:.0} MiB against a peak of {:.0} MiB",
            planned / 1048576.0,
            peak / 1048576.0
        );
    }
}
