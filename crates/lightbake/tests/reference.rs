//! The brute-force path tracer used as a reference: the furnace's known answer and agreement
//! with the radiosity solve on the Cornell box.

mod common;

use glam::Vec3;
use lightbake::analysis::reference::irradiance;
use lightbake::context::Prepared;
use lightbake::lights::Emitters;
use lightbake::scene::testscenes::{CornellLight, cornell_box, furnace_box};
use lightbake::settings::BakeSettings;

fn prepared(scene: &lightbake::Scene, density: f32) -> Prepared {
    let mut s = BakeSettings::medium();
    s.layout.texel_density = Some(density);
    s.layout.texel_density_from_scene = false;
    Prepared::new(scene, &s).unwrap()
}

#[test]
fn path_tracer_matches_the_furnace() {
    for rho in [0.5f32, 0.9] {
        let prep = prepared(&furnace_box(1.0, rho, 10.0), 4.0);
        let ctx = prep.ctx();
        let emitters = Emitters::collect(&prep.scene, &prep.rays);
        let e = std::f32::consts::PI * 10.0;
        let expected = rho * e / (1.0 - rho);
        let (mut sum, mut count) = (0.0f64, 0);
        for p in prep.patches.patches.iter().step_by(7) {
            let r = irradiance(&ctx, &emitters, &p.representative(), 4096, p.rng(1, 2));
            assert!(
                common::rel(r.direct.x, e) < 0.02,
                "ρ={rho}: direct {} vs {e}",
                r.direct.x
            );
            // Each point within its Monte Carlo noise (long paths at ρ = 0.9)…
            assert!(
                common::rel(r.indirect.x, expected) < 0.08,
                "ρ={rho}: indirect {} vs {expected}",
                r.indirect.x
            );
            sum += r.indirect.x as f64;
            count += 1;
        }
        // …and their mean within 2%.
        let mean = (sum / count as f64) as f32;
        assert!(
            common::rel(mean, expected) < 0.02,
            "ρ={rho}: mean indirect {mean} vs {expected}"
        );
    }
}

#[test]
fn path_tracer_agrees_with_radiosity_on_the_cornell_box() {
    let prep = prepared(&cornell_box(CornellLight::Area), 24.0);
    let direct = lightbake::direct::direct_irradiance(&prep.ctx());
    let radiosity = common::radiosity_indirect(&prep, &direct, 2048);
    let ctx = prep.ctx();
    let emitters = Emitters::collect(&prep.scene, &prep.rays);
    // Per surface, area-weighted: the two estimates of the same indirect light.
    let mut sums = std::collections::BTreeMap::new();
    for (i, p) in prep.patches.patches.iter().enumerate().step_by(5) {
        if !p.is_valid() {
            continue;
        }
        let r = irradiance(&ctx, &emitters, &p.representative(), 512, p.rng(3, 4));
        let name = prep.scene.instances[p.instance as usize].name.clone();
        let e = sums.entry(name).or_insert((Vec3::ZERO, Vec3::ZERO));
        e.0 += r.indirect * p.area;
        e.1 += radiosity[i] * p.area;
    }
    for (name, (pt, rad)) in sums {
        if name == "light" {
            continue; // black emitter: its indirect light is tiny and noisy
        }
        let ratio = pt.y / rad.y;
        assert!(
            (ratio - 1.0).abs() < 0.05,
            "{name}: path traced / radiosity = {ratio:.3}"
        );
    }
}
