//! The command line mapped onto the settings, one flag at a time.

use super::*;

/// Every field of `BakeSettings` has a flag: a command line that sets every flag away
/// from the preset changes every field (compared through the settings' JSON form, so a
/// new field without a flag fails here).
#[test]
fn every_setting_has_a_flag() {
    let cli = Cli::try_parse_from([
        "bake",
        "scene.gltf",
        "-o",
        "out",
        "--method=hybrid",
        "--solver=krylov-cg",
        "--basis=constant",
        "--transport-rays=7",
        "--cluster-texels=4",
        "--cluster-rays=5",
        "--cluster-tolerance=0.2",
        "--transport-budget=9",
        "--tolerance=0.25",
        "--max-solver-iterations=11",
        "--stochastic-rays=13",
        "--vpl-particles=17",
        "--vpl-cut=33",
        "--vpl-time-budget=1.5",
        "--vpl-sequence=jittered",
        "--vpl-clamp=0.5",
        "--bias-compensation",
        "--vpl-compensation-rays=19",
        "--vpl-max-depth=5",
        "--texel-density=3",
        "--ignore-scene-density",
        "--texel-budget=5000",
        "--samples=23",
        "--uniform-density",
        "--sky-samples=29",
        "--max-closed-form-emitters=31",
        "--padding=3",
        "--max-page-size=512",
        "--format=hdr",
        "--no-preview",
        "--reunwrap",
        "--no-contact-fit",
        "--no-stitch",
        "--even-gather",
        "--gather-cache=16",
        "--cache-accuracy=0.75",
        "--denoise=off",
        "--denoise-radius=5",
        "--irradiance-volume",
        "--probe-spacing=0.5",
        "--probe-rays=43",
        "--probes-per-headroom=5",
        "--volume-regions=3",
        "--volume-world-axes",
        "--threads=1",
        "--seed=37",
        "--memory-budget=41",
        "--max-rays=1000000000",
        "--target-error=0.05",
        "--grid-error-points=47",
        "--verify=64",
        "--verify-paths=256",
        "--light-convention=bevy",
        "--group=night=lamp,sky",
    ])
    .unwrap();
    let args = cli.bake.expect("the bare form is a bake");
    // Every leaf of the settings, by its path (`direct.samples_per_texel`); the output
    // formats count as one.
    fn leaves(
        path: &str,
        v: serde_json::Value,
        out: &mut std::collections::BTreeMap<String, serde_json::Value>,
    ) {
        match v {
            serde_json::Value::Object(m) if path != "formats" => {
                for (k, v) in m {
                    let p = if path.is_empty() {
                        k
                    } else {
                        format!("{path}.{k}")
                    };
                    leaves(&p, v, out);
                }
            }
            v => {
                out.insert(path.to_string(), v);
            }
        }
    }
    let json = |s: &BakeSettings| {
        let mut out = std::collections::BTreeMap::new();
        leaves("", serde_json::to_value(s).unwrap(), &mut out);
        out
    };
    let preset = json(&BakeSettings::medium());
    let set = json(&settings_from(&args));
    for (field, value) in &preset {
        assert_ne!(&set[field], value, "no flag changes `{field}`");
    }
    assert_eq!(preset.len(), set.len());
    assert!(
        preset.contains_key("direct.samples_per_texel"),
        "{preset:?}"
    );
}

#[test]
fn sky_is_r_comma_g_comma_b() {
    assert_eq!(parse_rgb("1, 2.5,3"), Ok([1.0, 2.5, 3.0]));
    assert!(parse_rgb("1 2 3").is_err());
    assert!(parse_rgb("1,2").unwrap_err().contains("three numbers"));
}
