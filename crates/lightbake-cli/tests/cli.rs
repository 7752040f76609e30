//! The `bake` command: a successful bake writes every output; bad input exits non-zero with a
//! one-line cause naming the problem.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

fn bake(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_bake"))
        .args(args)
        .output()
        .expect("run bake")
}

fn asset(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../assets")
        .join(name)
}

fn stderr_line(out: &Output) -> String {
    let text = String::from_utf8_lossy(&out.stderr).into_owned();
    let errors: Vec<&str> = text.lines().filter(|l| l.starts_with("error:")).collect();
    assert_eq!(errors.len(), 1, "expected one error line, got: {text}");
    errors[0].to_string()
}

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
        stdout.contains("area lights    run") && stdout.contains("direct lights  skip"),
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
            .any(|s| s["name"] == "direct" && s["rays"].as_u64().unwrap() > 0)
    );
    assert!(
        report["plan"]["stages"]
            .as_array()
            .unwrap()
            .iter()
            .any(|s| s["name"] == "sky" && s["run"] == false)
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
        stdout.contains("sky            run")
            && stdout.contains("area lights    skip no emissive surfaces"),
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

/// Every visible file under `dir` (hidden temporaries and kept copies excluded), by relative
/// path, with its bytes.
fn files(dir: &Path) -> std::collections::BTreeMap<PathBuf, Vec<u8>> {
    let mut out = std::collections::BTreeMap::new();
    let mut stack = vec![dir.to_path_buf()];
    while let Some(d) = stack.pop() {
        for entry in std::fs::read_dir(&d).unwrap().flatten() {
            let path = entry.path();
            if entry.file_name().to_string_lossy().starts_with('.') {
                continue;
            }
            if path.is_dir() {
                stack.push(path);
            } else {
                let rel = path.strip_prefix(dir).unwrap().to_path_buf();
                out.insert(rel, std::fs::read(&path).unwrap());
            }
        }
    }
    out
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
        let now = files(&out);
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

/// Every output file of a bake, by name relative to `dir` (the report aside: its times
/// differ from run to run).
fn outputs(dir: &Path) -> std::collections::BTreeMap<PathBuf, Vec<u8>> {
    let mut out = files(dir);
    out.retain(|p, _| p.file_name().is_some_and(|n| n != "report.json"));
    out
}

fn run_ok(args: &[&str]) -> String {
    let out = bake(args);
    assert!(
        out.status.success(),
        "bake {args:?}: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8_lossy(&out.stdout).into_owned()
}

/// `prepare`, every shard (each its own process, all at once and waiting for each other, or
/// one stage per run), `merge`: the outputs are the one-process bake's, byte for byte.
#[test]
fn a_split_bake_equals_the_one_process_bake_for_any_shard_count() {
    let dir = tempfile::tempdir().unwrap();
    let cases: [(&str, &[&str]); 3] = [
        // The hierarchical solve: direct light, final gather and correction split.
        (
            "cornell_box.gltf",
            &[
                "--quality",
                "medium",
                "--texel-density",
                "64",
                "--solver",
                "hierarchical",
            ],
        ),
        (
            "sunlit_room.gltf",
            &[
                "--quality",
                "preview",
                "--texel-density",
                "10",
                "--solver",
                "hierarchical",
            ],
        ),
        // The full matrix (auto at this size), a volume and a light baked indirect only: the
        // direct light split, the rest in the merge.
        (
            "cornell_box_point.gltf",
            &[
                "--quality",
                "preview",
                "--texel-density",
                "40",
                "--irradiance-volume",
                "--probe-rays",
                "32",
                "--indirect-only",
                "ceiling_point",
            ],
        ),
    ];
    for (k, (scene, flags)) in cases.iter().enumerate() {
        let scene = asset(scene);
        let whole = dir.path().join(format!("whole{k}"));
        let mut args = vec![
            scene.to_str().unwrap(),
            "-o",
            whole.to_str().unwrap(),
            "--quiet",
        ];
        args.extend_from_slice(flags);
        run_ok(&args);
        let expected = outputs(&whole);
        assert!(expected.len() >= 4);
        for (count, waves) in [(1u32, false), (3, false), (7, true)] {
            let work = dir.path().join(format!("work{k}_{count}"));
            let merged = dir.path().join(format!("merged{k}_{count}"));
            let mut args = vec![
                "prepare",
                scene.to_str().unwrap(),
                "-o",
                work.to_str().unwrap(),
            ];
            args.extend_from_slice(flags);
            run_ok(&args);
            let n = count.to_string();
            let shard = |i: u32, extra: &[&str]| {
                let mut c = Command::new(env!("CARGO_BIN_EXE_bake"));
                c.args(["shard", work.to_str().unwrap(), "--count", &n])
                    .args(extra)
                    .env("JOB_COMPLETION_INDEX", i.to_string());
                c
            };
            if waves {
                // One stage per run, as engines that run the stages as separate waves do:
                // three waves, each computing one stage (the matrix scene has one split
                // stage: its later waves find nothing left).
                let stages = ["direct", "final_gather", "correction"];
                for wave in 0..3 {
                    for i in 0..count {
                        let out = shard(i, &["--no-wait"]).output().unwrap();
                        assert!(
                            out.status.success(),
                            "{}",
                            String::from_utf8_lossy(&out.stderr)
                        );
                    }
                    for i in 0..count {
                        let part = |s: &str| work.join(format!("shards/{i}/{s}.bin"));
                        assert!(part("direct").exists());
                        if let Some(next) = stages.get(wave + 1) {
                            assert!(!part(next).exists(), "wave {wave} ran on to {next}");
                        }
                    }
                }
            } else {
                // All at once, each waiting for the others between stages.
                let mut children: Vec<_> =
                    (0..count).map(|i| shard(i, &[]).spawn().unwrap()).collect();
                for c in &mut children {
                    assert!(c.wait().unwrap().success());
                }
            }
            let log = run_ok(&[
                "merge",
                work.to_str().unwrap(),
                "-o",
                merged.to_str().unwrap(),
            ]);
            let got = outputs(&merged);
            assert_eq!(
                got.keys().collect::<Vec<_>>(),
                expected.keys().collect::<Vec<_>>(),
                "{scene:?}, {count} shards"
            );
            for (name, bytes) in &expected {
                assert!(
                    got[name] == *bytes,
                    "{scene:?}, {count} shards: {} differs from the one-process bake",
                    name.display()
                );
            }
            assert!(log.contains(&format!("direct: {count} shards")), "{log}");
            let report: serde_json::Value =
                serde_json::from_slice(&std::fs::read(merged.join("report.json")).unwrap())
                    .unwrap();
            assert_eq!(
                report["split"][0]["parts"].as_array().unwrap().len(),
                count as usize
            );
        }
    }
}

/// A missing shard is named by the merge; a shard re-run rewrites only its own parts; a
/// shard run with another count, or a scene (its document or an image it uses) changed since
/// prepare, is refused.
#[test]
fn split_bakes_name_missing_shards_and_refuse_mixed_work() {
    let dir = tempfile::tempdir().unwrap();
    let scene_dir = dir.path().join("scene");
    std::fs::create_dir_all(&scene_dir).unwrap();
    for f in ["cornell_box.gltf", "cornell_box.bin"] {
        std::fs::copy(asset(f), scene_dir.join(f)).unwrap();
    }
    let scene = scene_dir.join("cornell_box.gltf");
    // The first material takes its colour from an image file beside the scene.
    let paint = scene_dir.join("paint.png");
    let write_paint = |rgba: [u8; 4]| {
        image::RgbaImage::from_pixel(4, 4, image::Rgba(rgba))
            .save(&paint)
            .unwrap()
    };
    write_paint([200, 100, 50, 255]);
    let mut json: serde_json::Value =
        serde_json::from_slice(&std::fs::read(&scene).unwrap()).unwrap();
    json["images"] = serde_json::json!([{ "uri": "paint.png" }]);
    json["textures"] = serde_json::json!([{ "source": 0 }]);
    json["materials"][0]["pbrMetallicRoughness"]["baseColorTexture"] =
        serde_json::json!({ "index": 0 });
    std::fs::write(&scene, serde_json::to_vec(&json).unwrap()).unwrap();
    let work = dir.path().join("work");
    let w = work.to_str().unwrap();
    let flags = [
        "--quality",
        "preview",
        "--texel-density",
        "32",
        "--solver",
        "hierarchical",
    ];
    let mut args = vec!["prepare", scene.to_str().unwrap(), "-o", w];
    args.extend_from_slice(&flags);
    run_ok(&args);
    for i in ["0", "2"] {
        run_ok(&["shard", w, "--index", i, "--count", "3", "--no-wait"]);
    }
    let out = bake(&["merge", w, "-o", dir.path().join("out").to_str().unwrap()]);
    assert!(!out.status.success());
    let line = stderr_line(&out);
    assert!(line.contains("[1]") && line.contains("direct"), "{line}");
    // A re-run of shard 0 touches nothing of shard 2's.
    let part = work.join("shards/2/direct.bin");
    let before = std::fs::metadata(&part).unwrap().modified().unwrap();
    run_ok(&["shard", w, "--index", "0", "--count", "3", "--no-wait"]);
    assert_eq!(
        std::fs::metadata(&part).unwrap().modified().unwrap(),
        before
    );
    // Another count for shard 1: the other shards' parts were written for 3.
    let out = bake(&["shard", w, "--index", "1", "--count", "4", "--no-wait"]);
    assert!(!out.status.success());
    assert!(
        stderr_line(&out).contains("same --count"),
        "{}",
        stderr_line(&out)
    );
    assert!(!work.join("shards/1").exists(), "nothing written");
    // An index beyond the count, no index at all, a changed scene.
    let out = bake(&["shard", w, "--index", "3", "--count", "3"]);
    assert!(stderr_line(&out).contains("--index 3"));
    let out = Command::new(env!("CARGO_BIN_EXE_bake"))
        .args(["shard", w, "--count", "3"])
        .env_remove("JOB_COMPLETION_INDEX")
        .env_remove("SLURM_ARRAY_TASK_ID")
        .output()
        .unwrap();
    assert!(stderr_line(&out).contains("JOB_COMPLETION_INDEX"));
    write_paint([200, 100, 51, 255]);
    let out = bake(&["shard", w, "--index", "1", "--count", "3", "--no-wait"]);
    assert!(
        stderr_line(&out).contains("changed since"),
        "{}",
        stderr_line(&out)
    );
    write_paint([200, 100, 50, 255]);
    let original = std::fs::read_to_string(&scene).unwrap();
    let text = original.replacen("\"asset\"", "\"extras\": {\"changed\": 1}, \"asset\"", 1);
    std::fs::write(&scene, text).unwrap();
    let out = bake(&["shard", w, "--index", "1", "--count", "3", "--no-wait"]);
    assert!(
        stderr_line(&out).contains("changed since"),
        "{}",
        stderr_line(&out)
    );
    std::fs::write(&scene, original).unwrap();
    // The shared folder mounted elsewhere: the scene is found beside the work folder as it
    // was, or where --scene says.
    let mount = dir.path().join("mounted");
    std::fs::create_dir_all(&mount).unwrap();
    std::fs::rename(&scene_dir, mount.join("scene")).unwrap();
    std::fs::rename(&work, mount.join("work")).unwrap();
    let w = mount.join("work");
    let w = w.to_str().unwrap();
    run_ok(&["shard", w, "--index", "1", "--count", "3", "--no-wait"]);
    assert!(mount.join("work/shards/1/direct.bin").exists());
    let elsewhere = dir.path().join("elsewhere");
    std::fs::rename(mount.join("scene"), &elsewhere).unwrap();
    let out = bake(&["shard", w, "--index", "1", "--count", "3", "--no-wait"]);
    assert!(
        stderr_line(&out).contains("--scene"),
        "{}",
        stderr_line(&out)
    );
    let moved = elsewhere.join("cornell_box.gltf");
    let args = ["--index", "1", "--count", "3", "--no-wait", "--scene"];
    let mut cmd = vec!["shard", w];
    cmd.extend_from_slice(&args);
    cmd.push(moved.to_str().unwrap());
    run_ok(&cmd);
    assert!(mount.join("work/shards/1/final_gather.bin").exists());
}

/// A work folder prepared again (here with more direct-light samples, which leave the patches
/// as they were) takes no part of the previous preparation: the merge refuses until the
/// shards run again, then equals the one-process bake of the new settings.
#[test]
fn a_work_folder_prepared_again_takes_no_part_of_the_previous_preparation() {
    let dir = tempfile::tempdir().unwrap();
    let scene = asset("cornell_box.gltf");
    let scene = scene.to_str().unwrap();
    let work = dir.path().join("work");
    let w = work.to_str().unwrap();
    let flags = |samples: &'static str| {
        [
            "--quality",
            "preview",
            "--texel-density",
            "32",
            "--solver",
            "hierarchical",
            "--samples",
            samples,
        ]
    };
    let prepare = |samples: &'static str| {
        let mut args = vec!["prepare", scene, "-o", w];
        args.extend_from_slice(&flags(samples));
        run_ok(&args);
    };
    let wave = || {
        for i in ["0", "1", "2"] {
            run_ok(&["shard", w, "--index", i, "--count", "3", "--no-wait"]);
        }
    };
    prepare("4");
    wave();
    prepare("16");
    let merged = dir.path().join("merged");
    let m = merged.to_str().unwrap();
    let out = bake(&["merge", w, "-o", m]);
    assert!(!out.status.success());
    assert!(
        stderr_line(&out).contains("this preparation"),
        "{}",
        stderr_line(&out)
    );
    for _ in 0..3 {
        wave();
    }
    run_ok(&["merge", w, "-o", m]);
    let whole = dir.path().join("whole");
    let mut args = vec![scene, "-o", whole.to_str().unwrap(), "--quiet"];
    args.extend_from_slice(&flags("16"));
    run_ok(&args);
    let expected = outputs(&whole);
    let got = outputs(&merged);
    assert_eq!(
        got.keys().collect::<Vec<_>>(),
        expected.keys().collect::<Vec<_>>()
    );
    for (name, bytes) in &expected {
        assert!(got[name] == *bytes, "{} differs", name.display());
    }
}
