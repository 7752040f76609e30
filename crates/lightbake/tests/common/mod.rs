//! Helpers shared by the workspace integration tests.
#![allow(dead_code)]

use glam::{Affine3A, Vec2, Vec3};
use lightbake::bake::BakeOutput;
use lightbake::progress::Progress;
use lightbake::scene::testscenes::plane;
use lightbake::scene::{Instance, Material, Mesh, Scene};
use lightbake::settings::BakeSettings;

/// Every radiosity solver (not `Auto`).
pub const ALL_SOLVERS: [lightbake::settings::SolverChoice; 7] = {
    use lightbake::settings::SolverChoice::*;
    [
        Jacobi,
        GaussSeidel,
        Shooting,
        StochasticJacobi,
        Krylov,
        KrylovCg,
        Direct,
    ]
};

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
    s.method = lightbake::settings::Method::Direct;
    s.texel_density = density;
    s.texel_density_from_scene = false;
    s.samples_per_texel = spp;
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
