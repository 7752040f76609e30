//! Every stage reads a surface's diffuse albedo from one function
//! (`Material::diffuse_albedo`), which samples the base-colour texture at the texture
//! coordinate set the material names. The scene where this matters: a floor whose texture is
//! mapped by `TEXCOORD_1` (black on one side, white on the other), while its `TEXCOORD_0`
//! points every vertex at the black texel. A stage that sampled set 0 would see a black floor;
//! one that fell back to the texture's mean would see uniform grey.

use glam::{Affine3A, Vec2, Vec3};
use lightbake::context::Prepared;
use lightbake::radiosity::Nodes;
use lightbake::scene::{Instance, Material, Mesh, Scene, Texture, TextureRef, Wrap};
use lightbake::settings::{BakeSettings, Basis};
use lightbake::vpl::walk::{albedo_at, mean_reflectivity};

/// Albedo factor of the floor's material.
const FACTOR: f32 = 0.8;

fn floor_scene() -> Scene {
    let mut scene = Scene {
        name: "texcoord 1 floor".into(),
        ..Scene::default()
    };
    scene.textures.push(Texture {
        name: "black | white".into(),
        width: 2,
        height: 1,
        rgba8: vec![[0, 0, 0, 255], [255, 255, 255, 255]],
        wrap_u: Wrap::ClampToEdge,
        wrap_v: Wrap::ClampToEdge,
    });
    let material = scene.add_material(Material {
        base_color_texture: Some(TextureRef {
            texture: 0,
            tex_coord: 1,
        }),
        ..Material::diffuse("floor", Vec3::splat(FACTOR))
    });
    // A 2 m square facing +Y; TEXCOORD_1 spans it, TEXCOORD_0 sits on the black texel.
    let corners = [(-1.0, -1.0), (1.0, -1.0), (1.0, 1.0), (-1.0, 1.0)];
    let mesh = scene.add_mesh(Mesh {
        name: "floor".into(),
        positions: corners.map(|(x, z)| Vec3::new(x, 0.0, z)).to_vec(),
        normals: vec![Vec3::Y; 4],
        uv0: Some(vec![Vec2::new(0.25, 0.5); 4]),
        uv1: Some(
            corners
                .map(|(x, z)| Vec2::new(0.5 * (x + 1.0), 0.5 * (1.0 - z)))
                .to_vec(),
        ),
        indices: vec![0, 2, 1, 0, 3, 2],
        material: Some(material),
        source: None,
    });
    scene
        .instances
        .push(Instance::new("floor", mesh, Affine3A::IDENTITY));
    scene
}

#[test]
fn every_stage_sees_the_albedo_of_the_texture_coordinate_set_the_material_names() {
    let scene = floor_scene();
    let settings = {
        let mut s = BakeSettings::preview();
        s.layout.texel_density = Some(8.0);
        s.layout.texel_density_from_scene = false;
        s
    };
    let prep = Prepared::new(&scene, &settings).unwrap();
    let ctx = prep.ctx();
    // The radiosity nodes: the albedo averaged over each texel's footprint.
    let nodes = Nodes::new(&ctx, Basis::Linear);
    let lum = |c: Vec3| c.dot(Vec3::new(0.2126, 0.7152, 0.0722));
    let (mut darkest, mut brightest) = (f32::MAX, 0.0f32);
    for (i, &pi) in nodes.patch.iter().enumerate() {
        let p = &prep.patches.patches[pi as usize];
        // The VPL walks' and the reference path tracer's albedo: at a ray hit from above.
        let hit = prep
            .rays
            .closest_hit(p.position + Vec3::Y, Vec3::NEG_Y, 0.0, 2.0)
            .expect("the ray from above hits the floor");
        let at_hit = albedo_at(&prep.scene, &prep.rays, &hit);
        let texel = nodes.albedo[i];
        assert!(
            (lum(texel) - lum(at_hit)).abs() < 0.06,
            "node {i} at {}: footprint albedo {texel} but {at_hit} at its centre",
            p.position
        );
        darkest = darkest.min(lum(texel));
        brightest = brightest.max(lum(texel));
    }
    assert!(
        darkest < 0.05 && brightest > 0.75,
        "the floor runs from black to white ({darkest} .. {brightest}), as TEXCOORD_1 maps it"
    );
    // Keller's ρ̄ is the texture's mean (half black, half white, sRGB-decoded) times the
    // factor; no point albedo exceeds the plan's upper bound, the factor.
    let rho_bar = mean_reflectivity(&prep.scene, &prep.rays);
    assert!((rho_bar - 0.5 * FACTOR).abs() < 1e-6, "{rho_bar}");
    assert!(brightest <= FACTOR + 1e-6);
}
