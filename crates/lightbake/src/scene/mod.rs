//! The engine-free scene the baker works on: meshes, their placed instances, materials,
//! textures, lights and the sky.
//!
//! # Units
//! Lengths are metres. Light quantities follow glTF (`KHR_lights_punctual`,
//! `KHR_materials_emissive_strength`), which are also Bevy's (see `docs/units.md`):
//!
//! | quantity | unit | Bevy |
//! |---|---|---|
//! | point / spot intensity | candela (cd) | `PointLight::intensity` lumens = 4π·cd |
//! | directional intensity | lux (lx) | `DirectionalLight::illuminance` |
//! | emissive, sky | luminance, nits (cd/m²) | `StandardMaterial::emissive` |
//! | lightmap texel | irradiance / π (lx/π) | `Lightmap` RGB × `base_color` |
//!
//! Colours are linear RGB; intensities multiply them.

use glam::{Affine3A, Mat3, Vec2, Vec3, Vec4};
use serde::Serialize;

use crate::error::{BakeError, Result};

/// Largest world coordinate a vertex may have, m (default and only value: 10⁹ m). Beyond it
/// f32 positions are more than 100 m apart, so nothing can be baked there; xatlas crashed on
/// a fuzzed scene with a vertex at 1.4·10²² m (`tests/fuzz_import.rs`).
pub const MAX_COORDINATE: f32 = 1e9;

pub mod gltf_accessor;
pub mod gltf_import;
pub mod gltf_write;
pub mod testscenes;

/// A triangle mesh in its own (local) space. Shared by every [`Instance`] that places it.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Mesh {
    /// Name used in messages (glTF: `mesh name / primitive index`).
    pub name: String,
    /// Vertex positions, metres in mesh space.
    pub positions: Vec<Vec3>,
    /// Unit vertex normals (computed by [`Mesh::compute_normals`] when the source has none).
    pub normals: Vec<Vec3>,
    /// Texture coordinates set 0 (material textures), if any.
    pub uv0: Option<Vec<Vec2>>,
    /// Lightmap coordinates (set 1) in [0, 1]², if the source has them.
    pub uv1: Option<Vec<Vec2>>,
    /// Triangle list, three indices per triangle.
    pub indices: Vec<u32>,
    /// Index into [`Scene::materials`]; `None` means the glTF default material (white).
    pub material: Option<usize>,
    /// Where it came from in the source glTF, for the baked-glTF export.
    pub source: Option<GltfPrimitiveRef>,
}

/// A glTF `meshes[mesh].primitives[primitive]`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize)]
pub struct GltfPrimitiveRef {
    /// Mesh index in the glTF document.
    pub mesh: usize,
    /// Primitive index within that mesh.
    pub primitive: usize,
}

impl Mesh {
    /// Number of triangles.
    pub fn triangle_count(&self) -> usize {
        self.indices.len() / 3
    }

    /// The vertex indices of triangle `t`.
    ///
    /// # Panics
    /// If `t` is out of range.
    pub fn triangle(&self, t: usize) -> [usize; 3] {
        let i = &self.indices[3 * t..3 * t + 3];
        [i[0] as usize, i[1] as usize, i[2] as usize]
    }

    /// Area-weighted vertex normals from the triangles (for sources without normals).
    /// Vertices of degenerate triangles only get +Y.
    pub fn compute_normals(&mut self) {
        let mut n = vec![Vec3::ZERO; self.positions.len()];
        for t in 0..self.triangle_count() {
            let [a, b, c] = self.triangle(t);
            let (pa, pb, pc) = (self.positions[a], self.positions[b], self.positions[c]);
            let face = (pb - pa).cross(pc - pa); // length = 2 × area
            n[a] += face;
            n[b] += face;
            n[c] += face;
        }
        self.normals = n.into_iter().map(|v| v.normalize_or(Vec3::Y)).collect();
    }

    /// Checks that indices are in range and vertex data is finite.
    ///
    /// # Errors
    /// [`BakeError::PartialTriangle`], [`BakeError::IndexOutOfRange`],
    /// [`BakeError::NonFiniteVertex`] naming the mesh and the vertex or triangle.
    pub fn validate(&self) -> Result<()> {
        if self.indices.len() % 3 != 0 {
            return Err(BakeError::PartialTriangle {
                mesh: self.name.clone(),
                count: self.indices.len(),
            });
        }
        let n = self.positions.len();
        if let Some((k, &index)) = self
            .indices
            .iter()
            .enumerate()
            .find(|(_, i)| **i as usize >= n)
        {
            return Err(BakeError::IndexOutOfRange {
                mesh: self.name.clone(),
                triangle: k / 3,
                index,
                vertex_count: n,
            });
        }
        let finite3 = |attribute: &'static str, values: &[Vec3]| -> Result<()> {
            match values.iter().position(|v| !v.is_finite()) {
                Some(vertex) => Err(BakeError::NonFiniteVertex {
                    mesh: self.name.clone(),
                    vertex,
                    attribute,
                    value: format!("{:?}", values[vertex]),
                }),
                None => Ok(()),
            }
        };
        let finite2 = |attribute: &'static str, values: &[Vec2]| -> Result<()> {
            match values.iter().position(|v| !v.is_finite()) {
                Some(vertex) => Err(BakeError::NonFiniteVertex {
                    mesh: self.name.clone(),
                    vertex,
                    attribute,
                    value: format!("{:?}", values[vertex]),
                }),
                None => Ok(()),
            }
        };
        finite3("position", &self.positions)?;
        if self.normals.len() != n {
            return Err(BakeError::BadAccessor {
                context: format!("mesh '{}' NORMAL", self.name),
                message: format!("{} normals for {} positions", self.normals.len(), n),
            });
        }
        finite3("normal", &self.normals)?;
        for (attribute, uv) in [("TEXCOORD_0", &self.uv0), ("TEXCOORD_1", &self.uv1)] {
            if let Some(uv) = uv {
                if uv.len() != n {
                    return Err(BakeError::BadAccessor {
                        context: format!("mesh '{}' {attribute}", self.name),
                        message: format!("{} coordinates for {} positions", uv.len(), n),
                    });
                }
                finite2(attribute, uv)?;
            }
        }
        Ok(())
    }

    /// Total surface area in mesh units².
    pub fn area(&self) -> f32 {
        (0..self.triangle_count())
            .map(|t| {
                let [a, b, c] = self.triangle(t);
                let (pa, pb, pc) = (self.positions[a], self.positions[b], self.positions[c]);
                0.5 * (pb - pa).cross(pc - pa).length()
            })
            .sum()
    }
}

/// A mesh placed in the world.
#[derive(Clone, Debug, PartialEq)]
pub struct Instance {
    /// Name used in messages and the manifest (glTF node name, or `node N`).
    pub name: String,
    /// Index into [`Scene::meshes`].
    pub mesh: usize,
    /// Mesh space → world space (the whole node hierarchy, composed).
    pub transform: Affine3A,
    /// Receive a lightmap. Instances that are not baked still cast shadows and reflect light.
    pub bake: bool,
    /// Per-instance multiplier of the texel density (glTF node
    /// `extras.lightbake.texel_density_scale`). Default 1.
    pub texel_density_scale: f32,
    /// The glTF node it came from.
    pub gltf_node: Option<usize>,
}

impl Instance {
    /// Places `mesh` with `transform`, baked, at the default density.
    pub fn new(name: impl Into<String>, mesh: usize, transform: Affine3A) -> Self {
        Self {
            name: name.into(),
            mesh,
            transform,
            bake: true,
            texel_density_scale: 1.0,
            gltf_node: None,
        }
    }

    /// The matrix that takes mesh-space normals to world space (inverse transpose).
    pub fn normal_matrix(&self) -> Mat3 {
        Mat3::from(self.transform.matrix3).inverse().transpose()
    }

    /// Whether the transform is finite and invertible.
    ///
    /// # Errors
    /// [`BakeError::BadTransform`] naming the instance.
    pub fn validate(&self) -> Result<()> {
        let m = Mat3::from(self.transform.matrix3);
        if !(m.is_finite() && self.transform.translation.is_finite()) {
            return Err(BakeError::BadTransform {
                node: self.name.clone(),
                problem: "not finite",
            });
        }
        // Relative determinant test: |det| against the product of the column lengths.
        let scale = m.x_axis.length() * m.y_axis.length() * m.z_axis.length();
        if !(scale > 0.0 && (m.determinant().abs() / scale) > 1e-6) {
            return Err(BakeError::BadTransform {
                node: self.name.clone(),
                problem: "singular (zero scale)",
            });
        }
        Ok(())
    }
}

/// Reference from a material to a texture and the UV set it uses.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct TextureRef {
    /// Index into [`Scene::textures`].
    pub texture: usize,
    /// Which `TEXCOORD_n` the texture uses (only 0 is supported for sampling; others fall back
    /// to the texture's mean colour).
    pub tex_coord: u32,
}

/// A Lambertian material: what a lightmap baker needs of glTF's metallic-roughness model.
#[derive(Clone, Debug, PartialEq)]
pub struct Material {
    /// Name used in messages.
    pub name: String,
    /// Linear RGBA base colour factor (`baseColorFactor`). The diffuse albedo is its RGB,
    /// multiplied by the texture, times (1 − metallic).
    pub base_color: Vec4,
    /// `baseColorTexture`, sRGB-encoded.
    pub base_color_texture: Option<TextureRef>,
    /// `metallicFactor`: metals have no diffuse reflection. Default 0 here (glTF says 1 when
    /// absent; the importer applies the glTF default).
    pub metallic: f32,
    /// Emitted luminance, nits, linear RGB: `emissiveFactor × emissive_strength`.
    pub emissive: Vec3,
    /// `emissiveTexture`, sRGB-encoded; multiplies `emissive`.
    pub emissive_texture: Option<TextureRef>,
    /// glTF `doubleSided`: both faces are real surfaces. Back faces of single-sided materials
    /// are treated as the inside of solid geometry when deciding texel validity.
    pub double_sided: bool,
}

impl Default for Material {
    /// The glTF default material: white, rough, dielectric, single-sided, no emission.
    fn default() -> Self {
        Self {
            name: "default".into(),
            base_color: Vec4::ONE,
            base_color_texture: None,
            metallic: 0.0,
            emissive: Vec3::ZERO,
            emissive_texture: None,
            double_sided: false,
        }
    }
}

impl Material {
    /// A diffuse material of the given linear albedo.
    pub fn diffuse(name: impl Into<String>, albedo: Vec3) -> Self {
        Self {
            name: name.into(),
            base_color: albedo.extend(1.0),
            ..Self::default()
        }
    }

    /// An emitter of the given luminance (nits) with a black diffuse part.
    pub fn emitter(name: impl Into<String>, luminance: Vec3) -> Self {
        Self {
            name: name.into(),
            base_color: Vec4::new(0.0, 0.0, 0.0, 1.0),
            emissive: luminance,
            ..Self::default()
        }
    }

    /// Whether the material emits any light.
    pub fn is_emissive(&self) -> bool {
        self.emissive.max_element() > 0.0
    }

    /// Checks that factors are finite and non-negative.
    ///
    /// # Errors
    /// [`BakeError::BadMaterial`] naming the material.
    pub fn validate(&self) -> Result<()> {
        let bad = |message: String| BakeError::BadMaterial {
            material: self.name.clone(),
            message,
        };
        if !self.base_color.is_finite() || self.base_color.min_element() < 0.0 {
            return Err(bad(format!(
                "baseColorFactor {:?} must be finite and non-negative",
                self.base_color
            )));
        }
        if !self.emissive.is_finite() || self.emissive.min_element() < 0.0 {
            return Err(bad(format!(
                "emission {:?} nits must be finite and non-negative",
                self.emissive
            )));
        }
        if !(0.0..=1.0).contains(&self.metallic) {
            return Err(bad(format!(
                "metallicFactor {} must be in [0, 1]",
                self.metallic
            )));
        }
        Ok(())
    }
}

/// How a texture wraps outside [0, 1].
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Wrap {
    /// Tile (glTF default).
    #[default]
    Repeat,
    /// Tile, mirrored every other time.
    MirroredRepeat,
    /// Clamp to the edge texel.
    ClampToEdge,
}

/// An 8-bit RGBA texture, decoded.
#[derive(Clone, Debug, PartialEq)]
pub struct Texture {
    /// Name or URI, for messages.
    pub name: String,
    /// Width in texels.
    pub width: u32,
    /// Height in texels.
    pub height: u32,
    /// RGBA8 texels, row-major from the top.
    pub rgba8: Vec<[u8; 4]>,
    /// Wrap mode along U.
    pub wrap_u: Wrap,
    /// Wrap mode along V.
    pub wrap_v: Wrap,
}

impl Texture {
    /// Bilinear sample at `uv` (glTF convention: (0,0) is the top-left of the image), decoded
    /// from sRGB to linear RGB; alpha stays linear.
    pub fn sample_srgb(&self, uv: Vec2) -> Vec4 {
        let (w, h) = (self.width as i64, self.height as i64);
        if w == 0 || h == 0 {
            return Vec4::ONE;
        }
        let x = uv.x * self.width as f32 - 0.5;
        let y = uv.y * self.height as f32 - 0.5;
        let (x0, y0) = (x.floor(), y.floor());
        let (fx, fy) = (x - x0, y - y0);
        let fetch = |xi: i64, yi: i64| -> Vec4 {
            let xi = wrap_index(xi, w, self.wrap_u);
            let yi = wrap_index(yi, h, self.wrap_v);
            let p = self.rgba8[(yi * w + xi) as usize];
            Vec4::new(
                srgb_to_linear(p[0]),
                srgb_to_linear(p[1]),
                srgb_to_linear(p[2]),
                p[3] as f32 / 255.0,
            )
        };
        let (x0, y0) = (x0 as i64, y0 as i64);
        let top = fetch(x0, y0).lerp(fetch(x0 + 1, y0), fx);
        let bottom = fetch(x0, y0 + 1).lerp(fetch(x0 + 1, y0 + 1), fx);
        top.lerp(bottom, fy)
    }

    /// Mean linear colour over the whole image.
    pub fn mean_srgb(&self) -> Vec4 {
        if self.rgba8.is_empty() {
            return Vec4::ONE;
        }
        let mut sum = [0f64; 4];
        for p in &self.rgba8 {
            sum[0] += srgb_to_linear(p[0]) as f64;
            sum[1] += srgb_to_linear(p[1]) as f64;
            sum[2] += srgb_to_linear(p[2]) as f64;
            sum[3] += p[3] as f64 / 255.0;
        }
        let n = self.rgba8.len() as f64;
        Vec4::new(
            (sum[0] / n) as f32,
            (sum[1] / n) as f32,
            (sum[2] / n) as f32,
            (sum[3] / n) as f32,
        )
    }
}

fn wrap_index(i: i64, n: i64, wrap: Wrap) -> i64 {
    match wrap {
        Wrap::Repeat => i.rem_euclid(n),
        Wrap::ClampToEdge => i.clamp(0, n - 1),
        Wrap::MirroredRepeat => {
            let period = 2 * n;
            let m = i.rem_euclid(period);
            if m < n { m } else { period - 1 - m }
        }
    }
}

/// The sRGB transfer function, decoded (IEC 61966-2-1), via a table.
pub fn srgb_to_linear(v: u8) -> f32 {
    static TABLE: std::sync::OnceLock<[f32; 256]> = std::sync::OnceLock::new();
    TABLE.get_or_init(|| {
        let mut t = [0f32; 256];
        for (i, slot) in t.iter_mut().enumerate() {
            let c = i as f32 / 255.0;
            *slot = if c <= 0.04045 {
                c / 12.92
            } else {
                ((c + 0.055) / 1.055).powf(2.4)
            };
        }
        t
    })[v as usize]
}

/// What kind of punctual light.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
#[serde(tag = "type", rename_all = "snake_case")]
pub enum LightKind {
    /// Emits equally in every direction from `position`.
    Point,
    /// A point light limited to a cone around `direction`; full intensity inside
    /// `inner_cone_angle`, smoothly falling to zero at `outer_cone_angle` (radians, from the
    /// axis), with the glTF/Bevy falloff.
    Spot {
        /// Radians, [0, outer).
        inner_cone_angle: f32,
        /// Radians, (inner, π/2].
        outer_cone_angle: f32,
    },
    /// Parallel light travelling along `direction` (the sun).
    Directional {
        /// Angular radius of the disc, radians (0 = hard shadows; the sun is ≈ 0.00465).
        angular_radius: f32,
    },
}

/// A punctual light (`KHR_lights_punctual`).
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Light {
    /// Name used in messages and the plan.
    pub name: String,
    /// Type and shape.
    pub kind: LightKind,
    /// Linear RGB colour; multiplied by `intensity`.
    pub color: Vec3,
    /// Candela for point and spot lights; lux for directional lights.
    pub intensity: f32,
    /// Distance (m) beyond which the light has no effect, with the smooth window
    /// `(1 − (d/range)⁴)²` that Bevy uses; `None` = infinite.
    pub range: Option<f32>,
    /// World position (point and spot).
    pub position: Vec3,
    /// Unit world direction the light travels (spot axis, sun direction): the node's −Z.
    pub direction: Vec3,
}

impl Light {
    /// Checks that parameters are finite and in range.
    ///
    /// # Errors
    /// [`BakeError::BadLight`] naming the light.
    pub fn validate(&self) -> Result<()> {
        let bad = |message: String| BakeError::BadLight {
            light: self.name.clone(),
            message,
        };
        if !self.color.is_finite() || self.color.min_element() < 0.0 {
            return Err(bad(format!(
                "colour {:?} must be finite and non-negative",
                self.color
            )));
        }
        if !self.intensity.is_finite() || self.intensity < 0.0 {
            return Err(bad(format!(
                "intensity {} must be finite and non-negative",
                self.intensity
            )));
        }
        if let Some(r) = self.range {
            if !(r.is_finite() && r > 0.0) {
                return Err(bad(format!("range {r} must be positive")));
            }
        }
        if !self.position.is_finite() {
            return Err(bad(format!("position {:?} is not finite", self.position)));
        }
        if !self.direction.is_finite() || (self.direction.length() - 1.0).abs() > 1e-3 {
            return Err(bad(format!(
                "direction {:?} must be a unit vector",
                self.direction
            )));
        }
        match self.kind {
            LightKind::Spot {
                inner_cone_angle,
                outer_cone_angle,
            } => {
                if !(0.0..=std::f32::consts::FRAC_PI_2).contains(&outer_cone_angle)
                    || !(0.0..=outer_cone_angle).contains(&inner_cone_angle)
                {
                    return Err(bad(format!(
                        "cone angles inner {inner_cone_angle} / outer {outer_cone_angle} rad must satisfy 0 ≤ inner ≤ outer ≤ π/2"
                    )));
                }
            }
            LightKind::Directional { angular_radius } => {
                if !(0.0..=0.5).contains(&angular_radius) {
                    return Err(bad(format!(
                        "angular radius {angular_radius} rad must be in [0, 0.5]"
                    )));
                }
            }
            LightKind::Point => {}
        }
        Ok(())
    }

    /// Short type name for the plan and messages.
    pub fn kind_name(&self) -> &'static str {
        match self.kind {
            LightKind::Point => "point",
            LightKind::Spot { .. } => "spot",
            LightKind::Directional { .. } => "directional",
        }
    }
}

/// A scene ready to bake.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Scene {
    /// Name used in messages (the file name for imported scenes).
    pub name: String,
    /// Meshes (one per glTF primitive).
    pub meshes: Vec<Mesh>,
    /// Placed meshes.
    pub instances: Vec<Instance>,
    /// Materials referenced by meshes.
    pub materials: Vec<Material>,
    /// Textures referenced by materials.
    pub textures: Vec<Texture>,
    /// Punctual lights.
    pub lights: Vec<Light>,
    /// Uniform sky luminance in nits, linear RGB, seen by rays that leave the scene. Black by
    /// default.
    pub sky: Vec3,
    /// The scene's suggested texel density (glTF `scene.extras.lightbake.texel_density`).
    pub texel_density_hint: Option<f32>,
    /// Warnings raised while building the scene (repairs made on import).
    pub warnings: Vec<String>,
}

impl Scene {
    /// The material of mesh `m` (the glTF default when it has none).
    pub fn material_of(&self, mesh: usize) -> std::borrow::Cow<'_, Material> {
        match self.meshes[mesh].material {
            Some(i) => std::borrow::Cow::Borrowed(&self.materials[i]),
            None => std::borrow::Cow::Owned(Material::default()),
        }
    }

    /// Number of triangles over all instances (the ray-tracing load).
    pub fn instanced_triangle_count(&self) -> usize {
        self.instances
            .iter()
            .map(|i| self.meshes[i.mesh].triangle_count())
            .sum()
    }

    /// Checks every mesh, instance (including that its world vertices lie within
    /// [`MAX_COORDINATE`] of the origin), material and light; names the first problem.
    ///
    /// # Errors
    /// The first [`BakeError`] found, or [`BakeError::NoTriangles`].
    pub fn validate(&self) -> Result<()> {
        for m in &self.meshes {
            m.validate()?;
            if let Some(mat) = m.material {
                if mat >= self.materials.len() {
                    return Err(BakeError::BadReference {
                        what: format!(
                            "mesh '{}' uses material {mat}, which does not exist",
                            m.name
                        ),
                    });
                }
            }
        }
        for inst in &self.instances {
            if inst.mesh >= self.meshes.len() {
                return Err(BakeError::BadReference {
                    what: format!(
                        "instance '{}' uses mesh {}, which does not exist",
                        inst.name, inst.mesh
                    ),
                });
            }
            inst.validate()?;
            let mesh = &self.meshes[inst.mesh];
            if let Some((vertex, p)) = mesh
                .positions
                .iter()
                .map(|&p| inst.transform.transform_point3(p))
                .enumerate()
                .find(|(_, p)| p.is_nan() || p.abs().max_element() > MAX_COORDINATE)
            {
                return Err(BakeError::FarVertex {
                    instance: inst.name.clone(),
                    mesh: mesh.name.clone(),
                    vertex,
                    position: format!("{p}"),
                    limit: MAX_COORDINATE,
                    spacing: MAX_COORDINATE * f32::EPSILON,
                });
            }
            if !(inst.texel_density_scale.is_finite() && inst.texel_density_scale > 0.0) {
                return Err(BakeError::BadSetting {
                    name: "texel_density_scale",
                    value: inst.texel_density_scale.to_string(),
                    message: format!("instance '{}': must be positive", inst.name),
                });
            }
        }
        for mat in &self.materials {
            mat.validate()?;
            for t in [mat.base_color_texture, mat.emissive_texture]
                .into_iter()
                .flatten()
            {
                if t.texture >= self.textures.len() {
                    return Err(BakeError::BadReference {
                        what: format!(
                            "material '{}' uses texture {}, which does not exist",
                            mat.name, t.texture
                        ),
                    });
                }
            }
        }
        for light in &self.lights {
            light.validate()?;
        }
        if !self.sky.is_finite() || self.sky.min_element() < 0.0 {
            return Err(BakeError::BadSetting {
                name: "sky",
                value: format!("{:?}", self.sky),
                message: "sky luminance must be finite and non-negative".into(),
            });
        }
        if self.instanced_triangle_count() == 0 {
            return Err(BakeError::NoTriangles {
                scene: self.name.clone(),
            });
        }
        Ok(())
    }

    /// World-space bounds of every instance: (min, max). Empty scenes give (0, 0).
    pub fn bounds(&self) -> (Vec3, Vec3) {
        let mut lo = Vec3::splat(f32::INFINITY);
        let mut hi = Vec3::splat(f32::NEG_INFINITY);
        for inst in &self.instances {
            for p in &self.meshes[inst.mesh].positions {
                let w = inst.transform.transform_point3(*p);
                lo = lo.min(w);
                hi = hi.max(w);
            }
        }
        if lo.x > hi.x {
            (Vec3::ZERO, Vec3::ZERO)
        } else {
            (lo, hi)
        }
    }

    /// The world-space bounds of one instance.
    pub fn instance_bounds(&self, instance: usize) -> (Vec3, Vec3) {
        let inst = &self.instances[instance];
        let mut lo = Vec3::splat(f32::INFINITY);
        let mut hi = Vec3::splat(f32::NEG_INFINITY);
        for p in &self.meshes[inst.mesh].positions {
            let w = inst.transform.transform_point3(*p);
            lo = lo.min(w);
            hi = hi.max(w);
        }
        (lo, hi)
    }

    /// Adds a mesh and returns its index.
    pub fn add_mesh(&mut self, mesh: Mesh) -> usize {
        self.meshes.push(mesh);
        self.meshes.len() - 1
    }

    /// Adds a material and returns its index.
    pub fn add_material(&mut self, material: Material) -> usize {
        self.materials.push(material);
        self.materials.len() - 1
    }
}
