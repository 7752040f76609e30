//! Helpers shared by the core's integration tests.
#![allow(dead_code)]

use glam::{Affine3A, Vec2, Vec3};
use lightbake::bake::BakeOutput;
use lightbake::progress::Progress;
use lightbake::scene::testscenes::{cuboid, furnace_box, plane, quad};
use lightbake::scene::{Instance, Light, LightKind, Material, Mesh, Scene};
use lightbake::settings::{BakeSettings, Method, SolverChoice};

/// Every radiosity solver (not `Auto`).
pub const ALL_SOLVERS: [SolverChoice; 8] = {
    use SolverChoice::*;
    [
        Jacobi,
        GaussSeidel,
        Shooting,
        StochasticJacobi,
        Krylov,
        KrylovCg,
        Direct,
        Hierarchical,
    ]
};

/// Calls `f` with the volume stage's view of `out`'s solution (its ray scene and emitters
/// built here), for gathering probes outside a bake.
pub fn with_solution<R>(
    out: &BakeOutput,
    f: impl FnOnce(&lightbake::probes::gather::Solution<'_>) -> R,
) -> R {
    let rays = lightbake::bvh::RayScene::build(&out.baked_scene);
    let emitters = lightbake::lights::Emitters::collect(&out.baked_scene, &rays);
    f(&lightbake::probes::gather::Solution {
        scene: &out.baked_scene,
        layout: &out.layout,
        pages: &out.pages,
        rays: &rays,
        emitters: &emitters,
    })
}

/// Bakes in memory and panics with the error on failure.
pub fn bake(scene: &Scene, settings: &BakeSettings) -> BakeOutput {
    lightbake::bake(scene, settings, &Progress::new())
        .unwrap_or_else(|e| panic!("bake failed: {e}"))
}

/// A `size × size` m white plane at y = 0 facing +Y with a planar TEXCOORD_1, so texel (i, j)
/// of its rectangle maps linearly onto the plane.
pub fn uv_plane(name: &str, size: f32) -> Mesh {
    let mut m = plane(name, size);
    m.uv1 = m.uv0.clone();
    m
}

/// A scene of the real-scene corpus, `assets/corpus/` + `file`, as the importer reads it.
pub fn corpus_scene(file: &str) -> Scene {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../assets/corpus")
        .join(file);
    lightbake::import_gltf(&path, lightbake::settings::LightConvention::GltfSpec)
        .unwrap_or_else(|e| panic!("{file}: {e}"))
        .scene
}

/// Adds `mesh` with material `albedo` at `transform`; returns the instance index.
pub fn add(scene: &mut Scene, mesh: Mesh, albedo: Vec3, transform: Affine3A, bake: bool) -> usize {
    let mat = scene.add_material(Material::diffuse(format!("{}_mat", mesh.name), albedo));
    let name = mesh.name.clone();
    let m = scene.add_mesh(Mesh {
        material: Some(mat),
        ..mesh
    });
    let mut inst = Instance::new(name, m, transform);
    inst.bake = bake;
    scene.instances.push(inst);
    scene.instances.len() - 1
}

/// Settings for analytic direct-light tests: direct light only, fixed density, no scene hint.
pub fn settings(density: f32, spp: u32) -> BakeSettings {
    let mut s = BakeSettings::medium();
    s.method = Method::Direct;
    s.layout.texel_density = Some(density);
    s.layout.texel_density_from_scene = false;
    s.direct.samples_per_texel = spp;
    // The texels as the direct pass computed them, unfiltered (the denoiser has its tests).
    s.finish.denoise = false;
    s
}

/// One texel of an instance's rectangle whose centre lies on the surface.
#[derive(Clone, Copy, Debug)]
pub struct TexelSample {
    /// Column and row inside the instance's rectangle.
    pub local: (u32, u32),
    /// World position of the texel centre.
    pub position: Vec3,
    /// Unit world normal there.
    pub normal: Vec3,
    /// Stored value (E/π).
    pub value: Vec3,
}

/// Every texel of `instance` whose centre is inside one of its triangles, with the world point
/// under the centre and the stored value.
pub fn texels(out: &BakeOutput, instance: usize) -> Vec<TexelSample> {
    let rect = out.layout.instances[instance].expect("instance is baked");
    let inst = &out.baked_scene.instances[instance];
    let mesh = &out.baked_scene.meshes[inst.mesh];
    let uv1 = mesh.uv1.as_ref().expect("uv1");
    let page = &out.pages[rect.page as usize];
    let scale = Vec2::new(rect.width as f32, rect.height as f32);
    let mut result = Vec::new();
    for j in 0..rect.height {
        for i in 0..rect.width {
            let q = Vec2::new(i as f32 + 0.5, j as f32 + 0.5);
            for t in 0..mesh.triangle_count() {
                let [a, b, c] = mesh.triangle(t);
                let (pa, pb, pc) = (uv1[a] * scale, uv1[b] * scale, uv1[c] * scale);
                let det = (pb - pa).perp_dot(pc - pa);
                if det.abs() < 1e-12 {
                    continue;
                }
                let u = (q - pa).perp_dot(pc - pa) / det;
                let v = (pb - pa).perp_dot(q - pa) / det;
                if u < 0.0 || v < 0.0 || u + v > 1.0 {
                    continue;
                }
                let w = 1.0 - u - v;
                let local = mesh.positions[a] * w + mesh.positions[b] * u + mesh.positions[c] * v;
                let n = mesh.normals[a] * w + mesh.normals[b] * u + mesh.normals[c] * v;
                result.push(TexelSample {
                    local: (i, j),
                    position: inst.transform.transform_point3(local),
                    normal: inst.transform.transform_vector3(n).normalize(),
                    value: page.get(rect.x + i, rect.y + j),
                });
                break;
            }
        }
    }
    result
}

/// Relative difference, guarded for zero.
pub fn rel(a: f32, b: f32) -> f32 {
    (a - b).abs() / b.abs().max(1e-12)
}

/// The radiosity solution's indirect irradiance per patch (lux) for a prepared scene, with
/// `rays` Galerkin form-factor rays per node, solved to a relative residual of 10⁻⁸.
pub fn radiosity_indirect(
    prep: &lightbake::context::Prepared,
    direct: &[Vec3],
    rays: u32,
) -> Vec<Vec3> {
    use lightbake::progress::Progress;
    use lightbake::radiosity::{Nodes, monte_carlo};
    use lightbake::settings::{Basis, SolverChoice};
    use lightbake::solve::{SolveOptions, solve_matrix};
    let ctx = prep.ctx();
    let nodes = Nodes::new(&ctx, Basis::Linear);
    let transport = monte_carlo::build(&ctx, &nodes, rays, Basis::Linear, &Progress::new());
    let source = lightbake::radiosity::source(&nodes, direct);
    let system = lightbake::radiosity::system(&transport, &nodes, &source);
    let s = solve_matrix(
        SolverChoice::GaussSeidel,
        &system,
        &SolveOptions {
            tolerance: 1e-8,
            max_iterations: 10_000,
        },
    );
    lightbake::radiosity::per_patch(&nodes, &s.indirect, prep.patches.patches.len())
}

/// Area-weighted relative L2 difference ‖a − b‖/‖b‖ over the valid patches.
pub fn relative_l2(prep: &lightbake::context::Prepared, a: &[Vec3], b: &[Vec3]) -> f64 {
    let (mut num, mut den) = (0.0f64, 0.0f64);
    for (i, p) in prep.patches.patches.iter().enumerate() {
        if !p.is_valid() {
            continue;
        }
        num += p.area as f64 * (a[i] - b[i]).length_squared() as f64;
        den += p.area as f64 * b[i].length_squared() as f64;
    }
    (num / den.max(1e-300)).sqrt()
}

pub fn radiosity_settings(density: f32, solver: SolverChoice) -> BakeSettings {
    let mut s = settings(density, 4);
    s.method = Method::Radiosity;
    s.radiosity.solver = solver;
    s.radiosity.transport_rays = 64;
    s.radiosity.stochastic_rays_per_node = 4096;
    s
}

/// Two unit squares as baked instances.
pub fn two_squares(perpendicular: bool) -> Scene {
    let mut s = Scene::default();
    let mat = s.add_material(Material::diffuse("grey", Vec3::splat(0.5)));
    let a = quad(
        "a",
        [
            Vec3::new(0.0, 0.0, 0.0),
            Vec3::new(1.0, 0.0, 0.0),
            Vec3::new(1.0, 0.0, 1.0),
            Vec3::new(0.0, 0.0, 1.0),
        ],
        Vec3::Y,
    );
    let b = if perpendicular {
        quad(
            "b",
            [
                Vec3::new(0.0, 0.0, 0.0),
                Vec3::new(1.0, 0.0, 0.0),
                Vec3::new(1.0, 1.0, 0.0),
                Vec3::new(0.0, 1.0, 0.0),
            ],
            Vec3::Z,
        )
    } else {
        quad(
            "b",
            [
                Vec3::new(0.0, 1.0, 0.0),
                Vec3::new(1.0, 1.0, 0.0),
                Vec3::new(1.0, 1.0, 1.0),
                Vec3::new(0.0, 1.0, 1.0),
            ],
            Vec3::NEG_Y,
        )
    };
    for m in [a, b] {
        let id = s.add_mesh(Mesh {
            material: Some(mat),
            ..m
        });
        s.instances
            .push(Instance::new(format!("{id}"), id, Affine3A::IDENTITY));
    }
    // Something to bake with: a light, so the plan has work.
    s.lights.push(Light {
        name: "l".into(),
        kind: LightKind::Point,
        color: Vec3::ONE,
        intensity: 1.0,
        range: None,
        position: Vec3::new(0.5, 0.5, 0.5),
        direction: Vec3::NEG_Y,
        bake: lightbake::scene::LightBake::Full,
    });
    s
}

/// Medium settings with `method` at a fixed density (no scene hint).
pub fn method_settings(method: Method, density: f32) -> BakeSettings {
    let mut s = BakeSettings::medium();
    s.method = method;
    s.layout.texel_density = Some(density);
    s.layout.texel_density_from_scene = false;
    s
}

/// Whether every texel of every page is finite.
pub fn all_finite(out: &BakeOutput) -> bool {
    out.pages
        .iter()
        .all(|p| p.texels.iter().all(|t| t.is_finite()))
}

/// `scene` with every length multiplied by `s` (instances, lights, ranges).
/// A mesh of loose triangles (flat normals from the winding), `uv1` left to xatlas.
pub fn triangles(name: &str, tris: &[[Vec3; 3]]) -> Mesh {
    let mut m = Mesh {
        name: name.into(),
        positions: Vec::new(),
        normals: Vec::new(),
        uv0: None,
        uv1: None,
        indices: Vec::new(),
        material: None,
        source: None,
    };
    for t in tris {
        let n = (t[1] - t[0]).cross(t[2] - t[0]).normalize_or(Vec3::Y);
        for &p in t {
            m.indices.push(m.positions.len() as u32);
            m.positions.push(p);
            m.normals.push(n);
        }
    }
    m
}

/// The closed furnace (every surface emits E and reflects ρ) filled with the geometry that
/// breaks form factors: a 1 cm cube next to 1 m walls, a wedge whose faces meet at 5°, a
/// plate carrying sliver (1 µm wide), zero-area and collinear triangles, and two coincident
/// plates. Whatever the geometry, B = E/(1 − ρ) on every surface of a closed furnace, so any
/// ray that leaks, is lost or is counted twice shows up amplified by 1/(1 − ρ).
///
/// `parts` names the pieces to add: `tiny_cube`, `wedge`, `slivers`, `coincident`.
pub fn hard_furnace(rho: f32, e: f32, parts: &[&str]) -> Scene {
    let mut scene = furnace_box(1.0, rho, e);
    let mat = scene.add_material(Material {
        emissive: Vec3::splat(e),
        double_sided: true,
        ..Material::diffuse("hard", Vec3::splat(rho))
    });
    let put = |scene: &mut Scene, mesh: Mesh, at: Affine3A| {
        let name = mesh.name.clone();
        if !parts.iter().any(|p| name.starts_with(p)) {
            return;
        }
        let m = scene.add_mesh(Mesh {
            material: Some(mat),
            ..mesh
        });
        scene.instances.push(Instance::new(name, m, at));
    };
    let tiny = cuboid("tiny_cube", Vec3::splat(-0.005), Vec3::splat(0.005), false);
    put(
        &mut scene,
        tiny,
        Affine3A::from_translation(Vec3::new(0.25, -0.3, 0.2)),
    );
    // Two plates sharing the edge x = −0.3, y = 0, opening at 5°.
    let (a, b) = (5f32.to_radians().cos() * 0.4, 5f32.to_radians().sin() * 0.4);
    let z = 0.2;
    let wedge = triangles(
        "wedge",
        &[
            [
                Vec3::new(-0.3, 0.0, -z),
                Vec3::new(-0.3, 0.0, z),
                Vec3::new(0.1, 0.0, z),
            ],
            [
                Vec3::new(-0.3, 0.0, -z),
                Vec3::new(0.1, 0.0, z),
                Vec3::new(0.1, 0.0, -z),
            ],
            [
                Vec3::new(-0.3, 0.0, -z),
                Vec3::new(-0.3 + a, b, z),
                Vec3::new(-0.3, 0.0, z),
            ],
            [
                Vec3::new(-0.3, 0.0, -z),
                Vec3::new(-0.3 + a, b, -z),
                Vec3::new(-0.3 + a, b, z),
            ],
        ],
    );
    put(&mut scene, wedge, Affine3A::IDENTITY);
    // A plate with a sliver across it, a zero-area triangle and a collinear one.
    let (p0, p1, p2, p3) = (
        Vec3::new(-0.3, 0.3, -0.3),
        Vec3::new(-0.3, 0.3, 0.3),
        Vec3::new(0.3, 0.3, 0.3),
        Vec3::new(0.3, 0.3, -0.3),
    );
    let sliver = triangles(
        "slivers",
        &[
            [p0, p1, p2],
            [p0, p2, p3],
            [p0, p2, p2 + Vec3::new(0.0, 0.0, -1e-6)],
            [p1, p1, p3],
            [p0, (p0 + p2) * 0.5, p2],
        ],
    );
    put(&mut scene, sliver, Affine3A::IDENTITY);
    // Two identical plates in the same place.
    let plate = triangles(
        "coincident",
        &[[
            Vec3::new(-0.2, -0.35, -0.2),
            Vec3::new(-0.2, -0.35, 0.2),
            Vec3::new(0.2, -0.35, 0.2),
        ]],
    );
    put(&mut scene, plate.clone(), Affine3A::IDENTITY);
    put(
        &mut scene,
        Mesh {
            name: "coincident_twin".into(),
            ..plate
        },
        Affine3A::IDENTITY,
    );
    scene
}

/// Property-test settings of the fuzz tests: 500 cases from `seed`, so CI runs the same cases
/// every time; `PROPTEST_CASES` and `PROPTEST_RNG_SEED` (a number, or `random`) explore
/// further.
pub fn proptest_config(seed: u64) -> proptest::prelude::ProptestConfig {
    proptest_config_cases(seed, 500)
}

/// [`proptest_config`] with `cases` cases unless `PROPTEST_CASES` says otherwise.
pub fn proptest_config_cases(seed: u64, cases: u32) -> proptest::prelude::ProptestConfig {
    use proptest::test_runner::RngSeed;
    let env = |name: &str| std::env::var(name).ok();
    proptest::prelude::ProptestConfig {
        cases: env("PROPTEST_CASES")
            .and_then(|c| c.parse().ok())
            .unwrap_or(cases),
        rng_seed: match env("PROPTEST_RNG_SEED").as_deref() {
            Some("random") => RngSeed::Random,
            Some(s) => s.parse().map_or(RngSeed::Random, RngSeed::Fixed),
            None => RngSeed::Fixed(seed),
        },
        failure_persistence: None,
        ..proptest::prelude::ProptestConfig::default()
    }
}
