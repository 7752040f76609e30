//! `bake prepare`, `bake shard` and `bake merge` as separate processes over a work folder:
//! the merged outputs are the one-process bake's, byte for byte; missing, mixed and stale
//! work is named and refused.

mod common;

use std::process::Command;

use common::{asset, bake, outputs, run_ok, stderr_line};

/// A quick hierarchical bake: direct light, the final gather's pilot and rest, and the
/// correction are split.
const QUICK: [&str; 6] = [
    "--quality",
    "preview",
    "--texel-density",
    "32",
    "--solver",
    "hierarchical",
];

/// `prepare`, every shard (each its own process, all at once and waiting for each other, or
/// one stage per run), `merge`: the outputs are the one-process bake's, byte for byte.
#[test]
fn a_split_bake_equals_the_one_process_bake_for_any_shard_count() {
    let dir = tempfile::tempdir().unwrap();
    let cases: [(&str, &[&str]); 3] = [
        // The hierarchical solve: direct light, the final gather (pilot and rest) and the
        // correction split.
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
                // four waves, each computing one stage (the matrix scene has one split
                // stage: its later waves find nothing left).
                let stages = ["direct", "gather_pilot", "final_gather", "correction"];
                for wave in 0..stages.len() {
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
    let mut args = vec!["prepare", scene.to_str().unwrap(), "-o", w];
    args.extend_from_slice(&QUICK);
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
    assert!(mount.join("work/shards/1/gather_pilot.bin").exists());
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
        let mut f = QUICK.to_vec();
        f.extend(["--samples", samples]);
        f
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
    // One wave per split stage: direct light, the gather's pilot and rest, the correction.
    for _ in 0..4 {
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
