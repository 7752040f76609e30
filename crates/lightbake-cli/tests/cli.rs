//! The `bake` command: a successful bake writes every output; bad input exits non-zero with a
//! one-line cause naming the problem.

mod common;

use std::path::{Path, PathBuf};
use std::process::Command;

use common::{asset, bake, files, stderr_line};

#[test]
fn bakes_the_cornell_box() {
    let dir = tempfile::tempdir().unwrap();
    let out_dir = dir.path().join("out");
    let out = bake(&[
        asset("cornell_box.gltf").to_str().unwrap(),
        "-o",
        out_dir.to_str().unwrap(),
        "--quality",
        "preview",
        "--texel-density",
        "64",
        "--format",
        "exr,hdr,ktx2",
        "--quiet",
    ]);
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "{stdout}\n{}",
        String::from_utf8_lossy(&out.stderr)
    );
    for f in [
        "cornell_box.gltf",
        "cornell_box.bin",
        "manifest.json",
        "report.json",
        "lightmaps/lightmap_0.exr",
        "lightmaps/lightmap_0.hdr",
        "lightmaps/lightmap_0.ktx2",
        "lightmaps/lightmap_0.preview.png",
    ] {
        assert!(out_dir.join(f).exists(), "{f} missing\n{stdout}");
    }
    // The plan and the summary table are printed.
    assert!(
        stdout.contains("area lights  yes") && stdout.contains("lights       no"),
        "{stdout}"
    );
    assert!(
        stdout.contains("Mrays/s") && stdout.contains("total"),
        "{stdout}"
    );
    let report: serde_json::Value =
        serde_json::from_slice(&std::fs::read(out_dir.join("report.json")).unwrap()).unwrap();
    assert!(
        report["stages"]
            .as_array()
            .unwrap()
            .iter()
            .any(|s| s["stage"] == "direct" && s["rays"].as_u64().unwrap() > 0)
    );
    assert!(
        report["plan"]["sources"]
            .as_array()
            .unwrap()
            .iter()
            .any(|s| s["source"] == "sky" && s["used"] == false)
    );
}

#[test]
fn bad_input_exits_non_zero_with_one_line() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let out_dir = d.join("out");
    let out = out_dir.to_str().unwrap();

    let r = bake(&[d.join("nope.gltf").to_str().unwrap(), "-o", out]);
    assert_eq!(r.status.code(), Some(1));
    assert!(stderr_line(&r).contains("nope.gltf"));

    let bad = d.join("bad.gltf");
    std::fs::write(&bad, b"{\"asset\": 3}").unwrap();
    let r = bake(&[bad.to_str().unwrap(), "-o", out]);
    assert_eq!(r.status.code(), Some(1));
    assert!(stderr_line(&r).contains("not a valid glTF"));

    // No triangles: only an asset header.
    let empty = d.join("empty.gltf");
    std::fs::write(
        &empty,
        br#"{"asset": {"version": "2.0"}, "scenes": [{"nodes": []}], "scene": 0}"#,
    )
    .unwrap();
    let r = bake(&[empty.to_str().unwrap(), "-o", out]);
    assert_eq!(r.status.code(), Some(1));
    assert!(stderr_line(&r).contains("no triangles"));

    // NaN vertex data.
    let nan = d.join("nan.gltf");
    let bin: Vec<u8> = [0.0f32, 0.0, 0.0, 1.0, 0.0, 0.0, f32::NAN, 0.0, 1.0]
        .iter()
        .flat_map(|f| f.to_le_bytes())
        .collect();
    std::fs::write(d.join("nan.bin"), &bin).unwrap();
    std::fs::write(
        &nan,
        br#"{"asset": {"version": "2.0"}, "scene": 0, "scenes": [{"nodes": [0]}], "nodes": [{"name": "tri", "mesh": 0}],
            "meshes": [{"name": "broken", "primitives": [{"attributes": {"POSITION": 0}}]}],
            "buffers": [{"uri": "nan.bin", "byteLength": 36}],
            "bufferViews": [{"buffer": 0, "byteLength": 36}],
            "accessors": [{"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3", "min": [0, 0, 0], "max": [1, 0, 1]}]}"#,
    )
    .unwrap();
    let r = bake(&[nan.to_str().unwrap(), "-o", out]);
    assert_eq!(r.status.code(), Some(1));
    let line = stderr_line(&r);
    assert!(
        line.contains("broken") && line.contains("vertex 2") && line.contains("NaN"),
        "{line}"
    );

    // Unwritable output: the output directory is a file.
    let blocker = d.join("file");
    std::fs::write(&blocker, b"x").unwrap();
    let r = bake(&[
        asset("cornell_box.gltf").to_str().unwrap(),
        "-o",
        blocker.to_str().unwrap(),
        "--quality",
        "preview",
        "--quiet",
    ]);
    assert_eq!(r.status.code(), Some(1));
    assert!(stderr_line(&r).contains("cannot write"));

    // A bad setting names the flag's field.
    let r = bake(&[
        asset("cornell_box.gltf").to_str().unwrap(),
        "-o",
        out,
        "--padding",
        "0",
    ]);
    assert_eq!(r.status.code(), Some(1));
    assert!(stderr_line(&r).contains("padding"));
}

/// `bake --help` says what the tool does and lists every subcommand; `bake bake SCENE` is
/// the bare form; a bad command line exits with status 2 and clap's usage.
#[test]
fn help_lists_the_subcommands_and_both_forms_bake() {
    let help = bake(&["--help"]);
    assert!(help.status.success());
    let text = String::from_utf8_lossy(&help.stdout);
    assert!(
        text.starts_with("Bake lightmaps for a glTF scene"),
        "{text}"
    );
    assert!(text.contains("radiosity"), "{text}");
    for sub in ["bake", "convergence", "prepare", "shard", "merge"] {
        assert!(
            text.lines().any(|l| l.trim_start().starts_with(sub)),
            "--help does not list `{sub}`:\n{text}"
        );
    }
    let dir = tempfile::tempdir().unwrap();
    let out_dir = dir.path().join("out");
    let scene = asset("sunlit_room.gltf");
    for form in [&[][..], &["bake"][..]] {
        let mut args: Vec<&str> = form.to_vec();
        args.extend([
            scene.to_str().unwrap(),
            "-o",
            out_dir.to_str().unwrap(),
            "--plan-only",
        ]);
        let r = bake(&args);
        assert!(r.status.success(), "{args:?}: {}", stderr_line(&r));
        assert!(String::from_utf8_lossy(&r.stdout).contains("plan:"));
    }
    let missing = bake(&[scene.to_str().unwrap()]);
    assert_eq!(missing.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&missing.stderr).contains("--output"));
    assert_eq!(bake(&[]).status.code(), Some(2));
    assert_eq!(bake(&["shard"]).status.code(), Some(2));
}

#[test]
fn plan_only_does_not_write() {
    let dir = tempfile::tempdir().unwrap();
    let out_dir = dir.path().join("out");
    let r = bake(&[
        asset("sunlit_room.gltf").to_str().unwrap(),
        "-o",
        out_dir.to_str().unwrap(),
        "--plan-only",
    ]);
    assert!(r.status.success());
    let stdout = String::from_utf8_lossy(&r.stdout);
    assert!(
        stdout.contains("sky          yes")
            && stdout.contains("area lights  no   no emissive surfaces"),
        "{stdout}"
    );
    assert!(!out_dir.exists());
}

#[test]
fn convergence_study_writes_csv_markdown_and_plots() {
    let dir = tempfile::tempdir().unwrap();
    let out_dir = dir.path().join("study");
    let out = bake(&[
        "convergence",
        asset("cornell_box.gltf").to_str().unwrap(),
        "-o",
        out_dir.to_str().unwrap(),
        "--quick",
        "--texel-density",
        "16",
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let csv = std::fs::read_to_string(out_dir.join("convergence.csv")).unwrap();
    let mut lines = csv.lines();
    assert!(
        lines
            .next()
            .unwrap()
            .starts_with("curve,parameter,budget,seconds")
    );
    let rows: Vec<Vec<&str>> = lines.map(|l| l.split(',').collect()).collect();
    for curve in [
        "direct",
        "jacobi",
        "gauss-seidel",
        "shooting",
        "krylov",
        "krylov-cg",
        "stochastic-jacobi",
        "mc-linear",
        "mc-constant",
        "hierarchical",
        "hierarchical-coarse",
        "hemicube",
        "vpl-hybrid",
        "vpl-cut",
    ] {
        assert!(
            rows.iter().any(|r| r[0] == curve),
            "no {curve} row in\n{csv}"
        );
    }
    for r in &rows {
        let measured: f64 = r[5].parse().unwrap();
        assert!(
            measured.is_finite() && measured > 0.0 && measured < 1.0,
            "{r:?}"
        );
    }
    // More form-factor rays, less error.
    let mc: Vec<f64> = rows
        .iter()
        .filter(|r| r[0] == "mc-linear")
        .map(|r| r[5].parse().unwrap())
        .collect();
    assert!(mc[mc.len() - 1] < mc[0], "{mc:?}");
    let svg = std::fs::read_to_string(out_dir.join("convergence.svg")).unwrap();
    assert!(svg.contains("<svg") && svg.contains("vpl-hybrid"));
    let png = std::fs::read(out_dir.join("convergence.png")).unwrap();
    assert!(png.starts_with(b"\x89PNG"), "not a PNG");
    assert!(
        std::fs::read_to_string(out_dir.join("convergence.md"))
            .unwrap()
            .contains("| curve |")
    );
}

/// Writes `files` (relative path → bytes) under `dir`, which is emptied first.
fn restore(dir: &Path, files: &std::collections::BTreeMap<PathBuf, Vec<u8>>) {
    let _ = std::fs::remove_dir_all(dir);
    for (rel, bytes) in files {
        let path = dir.join(rel);
        std::fs::create_dir_all(path.parent().unwrap()).unwrap();
        std::fs::write(path, bytes).unwrap();
    }
}

#[test]
fn a_bake_killed_midway_leaves_every_output_whole() {
    let dir = tempfile::tempdir().unwrap();
    let scene = asset("cornell_box.gltf");
    let scene = scene.to_str().unwrap();
    let run = |out: &Path, seed: &str| {
        let o = out.to_str().unwrap().to_string();
        vec![
            scene.to_string(),
            "-o".into(),
            o,
            "--quiet".into(),
            "--texel-density".into(),
            "48".into(),
            "--seed".into(),
            seed.into(),
        ]
    };
    // The previous outputs (seed 1) and what a finished second bake writes (seed 2).
    let out = dir.path().join("out");
    let new = dir.path().join("new");
    for (path, seed) in [(&out, "1"), (&new, "2")] {
        let done = Command::new(env!("CARGO_BIN_EXE_bake"))
            .args(run(path, seed))
            .output()
            .unwrap();
        assert!(done.status.success(), "{done:?}");
    }
    let old_files = files(&out);
    let new_files = files(&new);
    assert!(old_files.len() >= 4, "{:?}", old_files.keys());
    // The report holds timings, so it differs between runs: it must parse, whole.
    let is_report = |p: &Path| p.file_name().is_some_and(|n| n == "report.json");
    // Kill the seed-2 bake over the old outputs after 0, 15, 30, … ms until one finishes on
    // its own: the kills land in every stage, the write included, whatever the machine's
    // speed (only the number of kills depends on it).
    let mut killed = 0;
    for step in 0.. {
        let mut child = Command::new(env!("CARGO_BIN_EXE_bake"))
            .args(run(&out, "2"))
            .stdout(std::process::Stdio::null())
            .stderr(std::process::Stdio::null())
            .spawn()
            .unwrap();
        std::thread::sleep(std::time::Duration::from_millis(15 * step));
        let finished = match child.try_wait().unwrap() {
            Some(status) => {
                assert!(status.success());
                true
            }
            None => {
                child.kill().unwrap(); // SIGKILL: no destructor runs
                let status = child.wait().unwrap();
                killed += usize::from(!status.success());
                status.success()
            }
        };
        let mut now = files(&out);
        // The state a killed bake keeps to resume is not an output: whole if it is there
        // (written under another name and renamed), gone once a bake finished.
        if now.remove(Path::new("lightbake.partial")).is_some() {
            assert!(!finished, "a finished bake left its partial state");
            let partial = lightbake::incremental::read_partial(&out, 1 << 30);
            assert!(
                matches!(partial, Ok(Some(_))),
                "killed after {} ms: {partial:?}",
                15 * step
            );
        }
        assert_eq!(
            now.keys().collect::<Vec<_>>(),
            old_files.keys().collect::<Vec<_>>(),
            "killed after {} ms: the set of outputs changed",
            15 * step
        );
        for (path, bytes) in &now {
            if is_report(path) {
                assert!(
                    serde_json::from_slice::<serde_json::Value>(bytes).is_ok(),
                    "killed after {} ms: {} is not whole JSON",
                    15 * step,
                    path.display()
                );
                continue;
            }
            assert!(
                bytes == &old_files[path] || bytes == &new_files[path],
                "killed after {} ms: {} is neither the old nor the new file",
                15 * step,
                path.display()
            );
        }
        if finished {
            // A finished bake replaced everything.
            for (path, bytes) in &now {
                assert!(
                    is_report(path) || bytes == &new_files[path],
                    "{}",
                    path.display()
                );
            }
            break;
        }
        // Put the previous outputs back for the next kill.
        restore(&out, &old_files);
    }
    println!("{killed} bakes killed before one finished");
    assert!(
        killed >= 3,
        "only {killed} bakes were killed before one finished"
    );
}

#[test]
fn mixed_lighting_and_an_irradiance_volume_from_the_command_line() {
    let dir = tempfile::tempdir().unwrap();
    let out_dir = dir.path().join("out");
    let scene = asset("cornell_box_point.gltf");
    let args = |extra: &[&str]| {
        let mut a = vec![
            scene.to_str().unwrap().to_string(),
            "-o".into(),
            out_dir.to_str().unwrap().into(),
            "--quality".into(),
            "preview".into(),
            "--texel-density".into(),
            "32".into(),
        ];
        a.extend(extra.iter().map(|s| s.to_string()));
        a
    };
    let run = |extra: &[&str]| {
        let a = args(extra);
        bake(&a.iter().map(String::as_str).collect::<Vec<_>>())
    };
    let out = run(&[
        "--lighting",
        "indirect",
        "--irradiance-volume",
        "--probe-rays",
        "32",
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(stdout.contains("indirect only"), "{stdout}");
    assert!(stdout.contains("irradiance volume"), "{stdout}");
    assert!(out_dir.join("irradiance_volumes/volume_0.ktx2").is_file());
    let gltf: serde_json::Value =
        serde_json::from_slice(&std::fs::read(out_dir.join("cornell_box_point.gltf")).unwrap())
            .unwrap();
    let light = &gltf["extensions"]["KHR_lights_punctual"]["lights"][0]["extras"]["lightbake"];
    assert_eq!(light["bake"], "indirect");
    assert!(light.get("baked").is_none(), "{light}");
    let volumes = &gltf["scenes"][0]["extras"]["lightbake"]["irradiance_volumes"];
    assert_eq!(volumes[0]["image"], "irradiance_volumes/volume_0.ktx2");

    // A light named that the scene does not have is a one-line error naming the lights.
    let out = run(&["--indirect-only", "lamp"]);
    assert!(!out.status.success());
    let line = stderr_line(&out);
    assert!(
        line.contains("'lamp'") && line.contains("ceiling_point"),
        "{line}"
    );
}

#[test]
fn light_groups_from_the_command_line() {
    let dir = tempfile::tempdir().unwrap();
    let out_dir = dir.path().join("out");
    let scene = asset("sunlit_room.gltf");
    let run = |extra: &[&str]| {
        let mut a = vec![
            scene.to_str().unwrap(),
            "-o",
            out_dir.to_str().unwrap(),
            "--quality",
            "preview",
            "--irradiance-volume",
            "--probe-rays",
            "32",
        ];
        a.extend(extra);
        bake(&a)
    };
    let out = run(&["--group", "day=sun"]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(stdout.contains("light group day: light sun"), "{stdout}");
    assert!(stdout.contains("light group ungrouped: sky"), "{stdout}");
    for group in ["day", "ungrouped"] {
        assert!(
            out_dir
                .join(format!("lightmaps/groups/{group}/lightmap_0.exr"))
                .is_file()
        );
        assert!(
            out_dir
                .join(format!("irradiance_volumes/groups/{group}/volume_0.ktx2"))
                .is_file()
        );
    }
    let manifest: serde_json::Value =
        serde_json::from_slice(&std::fs::read(out_dir.join("manifest.json")).unwrap()).unwrap();
    let groups = &manifest["light_groups"];
    assert_eq!(groups[0]["name"], "day");
    assert_eq!(groups[0]["members"][0], "light sun");
    assert_eq!(
        groups[0]["pages"][0]["exr"],
        "lightmaps/groups/day/lightmap_0.exr"
    );
    let gltf: serde_json::Value =
        serde_json::from_slice(&std::fs::read(out_dir.join("sunlit_room.gltf")).unwrap()).unwrap();
    let listed = &gltf["scenes"][0]["extras"]["lightbake"]["light_groups"];
    assert_eq!(listed[1]["name"], "ungrouped");
    assert_eq!(
        listed[1]["pages"][0],
        "lightmaps/groups/ungrouped/lightmap_0.exr"
    );
    assert_eq!(
        listed[1]["irradiance_volumes"][0],
        "irradiance_volumes/groups/ungrouped/volume_0.ktx2"
    );

    // A member the scene does not have is a one-line error naming the lights.
    let out = run(&["--group", "night=lamp"]);
    assert!(!out.status.success());
    let line = stderr_line(&out);
    assert!(
        line.contains("night=lamp") && line.contains("its lights: sun"),
        "{line}"
    );
}

#[test]
fn a_bake_with_light_groups_whose_sky_changed_is_relit_from_the_cache() {
    let dir = tempfile::tempdir().unwrap();
    let out_dir = dir.path().join("out");
    let scene = asset("sunlit_room.gltf");
    let run = |sky: &str, extra: &[&str]| {
        let mut a = vec![
            scene.to_str().unwrap(),
            "-o",
            out_dir.to_str().unwrap(),
            "--quality",
            "preview",
            "--group",
            "day=sun",
            "--sky",
            sky,
        ];
        a.extend(extra);
        let out = bake(&a);
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
        String::from_utf8_lossy(&out.stdout).into_owned()
    };
    let first = run("1000,1000,1000", &[]);
    assert!(first.contains("incremental: full bake"), "{first}");
    let files = common::outputs(&out_dir);
    let page = |group: &str| PathBuf::from(format!("lightmaps/groups/{group}/lightmap_0.exr"));
    // The sky twice as bright: the ungrouped group (the sky) weighted, the day group kept.
    let relit = run("2000,2000,2000", &[]);
    assert!(
        relit.contains("incremental: relit") && relit.contains("group ungrouped × (2.0000"),
        "{relit}"
    );
    assert!(relit.contains("relight"), "{relit}");
    let now = common::outputs(&out_dir);
    assert_eq!(now[&page("day")], files[&page("day")]);
    assert_ne!(now[&page("ungrouped")], files[&page("ungrouped")]);
    // Back to the first sky: the first bake's pages again, byte for byte.
    run("1000,1000,1000", &[]);
    let back = common::outputs(&out_dir);
    for f in [
        page("day"),
        page("ungrouped"),
        PathBuf::from("lightmaps/lightmap_0.exr"),
    ] {
        assert_eq!(back[&f], files[&f], "{}", f.display());
    }
    // A volume is not kept: a full bake that says so.
    let full = run(
        "1000,1000,1000",
        &["--irradiance-volume", "--probe-rays", "32"],
    );
    assert!(full.contains("incremental: full bake"), "{full}");
}
