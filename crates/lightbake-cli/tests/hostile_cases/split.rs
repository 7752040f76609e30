//! Split-bake work folders edited by hand, and split-bake flags out of range.

use serde_json::Value;

use super::gltf::Doc;
use super::{Case, Expect};

fn prepare() -> Vec<String> {
    [
        "prepare",
        "{scene}/scene.gltf",
        "-o",
        "{root}/work",
        "--quality",
        "preview",
        "--threads",
        "1",
        "--texel-density",
        "8",
    ]
    .map(String::from)
    .to_vec()
}

fn shard_all() -> Vec<String> {
    [
        "shard",
        "{root}/work",
        "--index",
        "0",
        "--count",
        "1",
        "--threads",
        "1",
    ]
    .map(String::from)
    .to_vec()
}

/// A case that prepares the base scene, applies `edits`, then runs `args`.
fn split_case(name: &str, args: &[&str], edits: Vec<(&str, super::Edit)>, expect: Expect) -> Case {
    let mut case = Case::bake(name, Doc::base().files(), expect);
    case.before = vec![prepare()];
    case.args = args.iter().map(|s| s.to_string()).collect();
    case.edits = edits.into_iter().map(|(p, e)| (p.to_string(), e)).collect();
    case.timeout = 60.0;
    case
}

fn units(bytes: Vec<u8>, f: impl FnOnce(&mut Value)) -> Vec<u8> {
    let mut v: Value = serde_json::from_slice(&bytes).unwrap();
    f(&mut v);
    serde_json::to_vec(&v).unwrap()
}

/// The cases.
pub fn cases() -> Vec<Case> {
    let shard = &[
        "shard",
        "{root}/work",
        "--index",
        "0",
        "--count",
        "1",
        "--threads",
        "1",
    ];
    let merge = &["merge", "{root}/work", "-o", "{out}", "--threads", "1"];
    let mut cases = vec![
        split_case(
            "units.json starts beyond the patches",
            shard,
            vec![("{root}/work/units.json", |b| {
                units(b, |v| {
                    let s = v["starts"].as_array_mut().unwrap();
                    let last = s.len() - 1;
                    s[last] = Value::from(1u64 << 31);
                })
            })],
            Expect::Refuse("units.json"),
        ),
        split_case(
            "units.json decreasing",
            shard,
            vec![("{root}/work/units.json", |b| {
                units(b, |v| {
                    let s = v["starts"].as_array_mut().unwrap();
                    s.swap(1, 2);
                })
            })],
            Expect::Refuse("units.json"),
        ),
        split_case(
            "units.json short",
            shard,
            vec![("{root}/work/units.json", |b| {
                units(b, |v| {
                    v["starts"].as_array_mut().unwrap().truncate(3);
                })
            })],
            Expect::Refuse("units.json"),
        ),
        split_case(
            "units.json empty lists",
            shard,
            vec![("{root}/work/units.json", |b| {
                units(b, |v| {
                    v["starts"] = Value::Array(Vec::new());
                    v["rays"] = Value::Array(Vec::new());
                })
            })],
            Expect::Refuse("units.json"),
        ),
        split_case(
            "patches.bin claims 2³² − 1 patches",
            shard,
            vec![("{root}/work/patches.bin", |mut b| {
                b[8..12].copy_from_slice(&u32::MAX.to_le_bytes());
                b
            })],
            Expect::Refuse("patches.bin"),
        ),
        split_case(
            "patches.bin footprint_start out of range",
            shard,
            vec![("{root}/work/patches.bin", |mut b| {
                // Patch 0's word 18 (footprint_start), after the magic and the count.
                let at = 12 + 18 * 4;
                b[at..at + 4].copy_from_slice(&(u32::MAX - 3).to_le_bytes());
                b
            })],
            Expect::Refuse("patches.bin"),
        ),
        split_case(
            "patches.bin page index out of range",
            shard,
            vec![("{root}/work/patches.bin", |mut b| {
                // Patch 0's x (word 2): beyond its page (not hashed apart from x and y).
                let at = 12 + 2 * 4;
                b[at..at + 4].copy_from_slice(&(1u32 << 30).to_le_bytes());
                b
            })],
            Expect::Refuse("patches.bin"),
        ),
        split_case(
            "patches.bin truncated",
            shard,
            vec![("{root}/work/patches.bin", |b| b[..b.len() / 2].to_vec())],
            Expect::Refuse("patches.bin"),
        ),
        split_case(
            "work.json garbled",
            shard,
            vec![("{root}/work/work.json", |_| b"{\"format\": 7".to_vec())],
            Expect::Refuse("work.json"),
        ),
        split_case(
            "shard --count 2³² − 1",
            &[
                "shard",
                "{root}/work",
                "--index",
                "0",
                "--count",
                "4294967295",
                "--threads",
                "1",
            ],
            vec![],
            Expect::Refuse("--count"),
        ),
        split_case(
            "shard --timeout inf",
            &[
                "shard",
                "{root}/work",
                "--index",
                "0",
                "--count",
                "2",
                "--timeout",
                "inf",
                "--threads",
                "1",
            ],
            vec![],
            Expect::Refuse("--timeout"),
        ),
        split_case(
            "shard --timeout 1e300",
            &[
                "shard",
                "{root}/work",
                "--index",
                "0",
                "--count",
                "2",
                "--timeout",
                "1e300",
                "--threads",
                "1",
            ],
            vec![],
            Expect::Refuse("--timeout"),
        ),
        split_case(
            "shard --timeout -1",
            &[
                "shard",
                "{root}/work",
                "--index",
                "0",
                "--count",
                "2",
                "--timeout=-1",
                "--threads",
                "1",
            ],
            vec![],
            Expect::Refuse("--timeout"),
        ),
        split_case(
            "shard --timeout NaN",
            &[
                "shard",
                "{root}/work",
                "--index",
                "0",
                "--count",
                "2",
                "--timeout",
                "NaN",
                "--threads",
                "1",
            ],
            vec![],
            Expect::Refuse("--timeout"),
        ),
    ];
    // A part whose header claims 2³² − 1 shards, read by the merge.
    let mut part = split_case(
        "part header claims 2³² − 1 shards",
        merge,
        vec![("{root}/work/shards/0/direct.bin", |b| {
            let len = u64::from_le_bytes(b[8..16].try_into().unwrap()) as usize;
            let mut head: Value = serde_json::from_slice(&b[16..16 + len]).unwrap();
            head["count"] = Value::from(u32::MAX);
            let text = serde_json::to_vec(&head).unwrap();
            let mut out = b[..8].to_vec();
            out.extend_from_slice(&(text.len() as u64).to_le_bytes());
            out.extend_from_slice(&text);
            out.extend_from_slice(&b[16 + len..]);
            out
        })],
        Expect::Refuse("shard"),
    );
    part.before.push(shard_all());
    cases.push(part);
    // A work folder whose scene is a FIFO.
    let mut fifo = split_case(
        "work folder whose scene is a FIFO",
        &[
            "shard",
            "{root}/work",
            "--index",
            "0",
            "--count",
            "1",
            "--threads",
            "1",
            "--scene",
            "{scene}/pipe.gltf",
        ],
        vec![],
        Expect::Refuse("pipe.gltf"),
    );
    fifo.fifos.push("pipe.gltf".into());
    fifo.timeout = 30.0;
    cases.push(fifo);
    cases
}
