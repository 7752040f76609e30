//! The unknowns of the radiosity system: one node per valid texel patch, with its diffuse
//! albedo (averaged over the texel's footprint), the area of its basis function and the flags
//! that say where geometry cuts its support.

use glam::Vec3;
use rayon::prelude::*;

use crate::context::BakeContext;
use crate::raster::{Footprint, Patch, Surface};

/// Footprint samples averaged for a texel's albedo.
const ALBEDO_SAMPLES: u32 = 16;

/// The unknowns: one node per valid patch.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Nodes {
    /// Node → patch index.
    pub patch: Vec<u32>,
    /// Patch → node index (`u32::MAX` for invalid patches).
    pub of_patch: Vec<u32>,
    /// Area of each node's basis function, ∫φᵢ dA, m²: for the constant basis the texel's
    /// covered area; for the linear basis the surface its bilinear weight spreads over (the
    /// texel area inside a chart, different at chart borders). Reciprocity (A_i·F_ij =
    /// A_j·F_ji) and power (B·A) are in these areas.
    pub area: Vec<f32>,
    /// Diffuse albedo of each node: base colour × (1 − metallic) × the base-colour texture
    /// averaged over the texel's footprint.
    pub albedo: Vec<Vec3>,
    /// Per node: whether geometry cuts its basis support (its anchor cannot see the anchor of
    /// a neighbouring node of its chart; see `HitMapper::split_flags`). Traced once, when the
    /// nodes are made (`Nodes::new`, in `basis.rs`), for every mapper made for these nodes.
    pub split: Vec<bool>,
    /// Per node: none of its texel's footprint points is open surface (the texel lies under
    /// geometry, and validity moved its point to the open side of it, possibly past the
    /// texel). Its representative point then stands for it: in its basis area, and as the
    /// start of its transport rays, as in the hemicube and the VPL gather. Sampling its
    /// support instead would find no start point (an empty row: no reflected light) or, at
    /// high ray counts, a few from a sliver of surface, so the row would depend on the ray
    /// count.
    pub sliver: Vec<bool>,
}

impl Nodes {
    /// One node per valid patch, with its albedo; its basis areas and support flags still
    /// empty (`Nodes::new` fills them, with a mapper over these nodes).
    pub(super) fn unknowns(ctx: &BakeContext<'_>) -> Self {
        let patches = &ctx.patches.patches;
        let mut of_patch = vec![u32::MAX; patches.len()];
        let mut patch = Vec::new();
        for (i, p) in patches.iter().enumerate() {
            if p.is_valid() {
                of_patch[i] = patch.len() as u32;
                patch.push(i as u32);
            }
        }
        let surface = Surface::new(ctx.scene, ctx.layout, ctx.rays);
        let albedo = patch
            .par_iter()
            .map(|&pi| texel_albedo(ctx, &surface, &patches[pi as usize]))
            .collect();
        Self {
            patch,
            of_patch,
            area: Vec::new(),
            albedo,
            split: Vec::new(),
            sliver: Vec::new(),
        }
    }

    /// Number of nodes.
    pub fn len(&self) -> usize {
        self.patch.len()
    }

    #[cfg(any(test, feature = "internals"))]
    /// Whether there are no nodes.
    pub fn is_empty(&self) -> bool {
        self.patch.is_empty()
    }

    /// Largest albedo component (the contraction factor bound of Jacobi-type iterations).
    pub fn max_albedo(&self) -> f32 {
        self.albedo
            .iter()
            .fold(0.0f32, |m, a| m.max(a.max_element()))
    }
}

/// Albedo of one texel: the material's diffuse albedo averaged over the texel's footprint.
fn texel_albedo(ctx: &BakeContext<'_>, surface: &Surface<'_>, p: &Patch) -> Vec3 {
    let inst = &ctx.scene.instances[p.instance as usize];
    let material = ctx.scene.material_of(inst.mesh);
    if material.base_color_texture.is_none() {
        return material.albedo_factor();
    }
    let mut sum = Vec3::ZERO;
    let mut rays = 0;
    let footprint = Footprint::new(
        ctx.layout,
        ctx.patches,
        surface,
        ctx.rays,
        p,
        ctx.settings.seed,
    );
    for s in 0..ALBEDO_SAMPLES {
        let sp = footprint.point(s, &mut rays);
        let info = ctx.rays.triangles[sp.triangle as usize];
        sum += ctx
            .scene
            .albedo_at(info.instance as usize, info.local as usize, sp.bary);
    }
    sum / ALBEDO_SAMPLES as f32
}
