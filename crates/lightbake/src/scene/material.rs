//! Materials: what a lightmap baker needs of glTF's metallic-roughness model, and the one
//! place the diffuse albedo of a surface point is computed.

use glam::{Vec2, Vec3, Vec4};

use super::Texture;
use crate::error::{BakeError, Result};

/// The texture coordinates of a surface point: `TEXCOORD_0` and `TEXCOORD_1` (`None` where the
/// mesh has no such set).
pub type TexCoords = [Option<Vec2>; 2];

/// Reference from a material to a texture and the UV set it uses.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct TextureRef {
    /// Index into [`Scene::textures`](super::Scene::textures).
    pub texture: usize,
    /// Which `TEXCOORD_n` the texture uses (0 or 1; a point without that set, or a higher set,
    /// takes the texture's mean colour).
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

    /// The diffuse albedo factor before the texture: base colour × (1 − metallic). No texture
    /// can raise the albedo above it.
    pub fn albedo_factor(&self) -> Vec3 {
        self.base_color.truncate() * (1.0 - self.metallic)
    }

    /// The diffuse albedo at a surface point with texture coordinates `uv`: the factor times
    /// the base-colour texture sampled at the set the material names (the texture's mean
    /// colour when the point has no such set). Every stage's albedo comes from here.
    pub fn diffuse_albedo(&self, textures: &[Texture], uv: TexCoords) -> Vec3 {
        let factor = self.albedo_factor();
        match self.base_color_texture {
            None => factor,
            Some(t) => factor * texture_at(&textures[t.texture], t, uv),
        }
    }

    /// The diffuse albedo averaged over the base-colour texture (its mean colour).
    pub fn mean_diffuse_albedo(&self, textures: &[Texture]) -> Vec3 {
        let factor = self.albedo_factor();
        match self.base_color_texture {
            None => factor,
            Some(t) => factor * textures[t.texture].mean_srgb().truncate(),
        }
    }

    /// The emitted luminance at a surface point with texture coordinates `uv`, nits: the
    /// emission times the emissive texture (sampled as [`Self::diffuse_albedo`] samples).
    pub fn emission(&self, textures: &[Texture], uv: TexCoords) -> Vec3 {
        match self.emissive_texture {
            None => self.emissive,
            Some(t) => self.emissive * texture_at(&textures[t.texture], t, uv),
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

/// Linear RGB of texture `t` at the set of `uv` it names, or its mean colour.
fn texture_at(texture: &Texture, t: TextureRef, uv: TexCoords) -> Vec3 {
    match uv.get(t.tex_coord as usize).copied().flatten() {
        Some(uv) => texture.sample_srgb(uv).truncate(),
        None => texture.mean_srgb().truncate(),
    }
}
