//! Triangle meshes in their own space, shared by the instances that place them.

use glam::{Vec2, Vec3};
use serde::Serialize;

use super::TexCoords;
use crate::error::{BakeError, Result};

/// A triangle mesh in its own (local) space. Shared by every [`Instance`](super::Instance) that places it.
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
    /// Index into [`Scene::materials`](super::Scene::materials); `None` means the glTF default material (white).
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

/// Largest angle, in degrees, between a vertex normal and a triangle's face normal that the
/// triangle's shading normal follows ([`Mesh::corner_normals`]). Smooth meshes
/// keep theirs (a six-sided cylinder's vertex normals are 30° off its faces); normals
/// averaged across a right-angled edge (45° off, 54.7° at a box's corner) are creased.
pub const CREASE_DEGREES: f32 = 40.0;

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

    /// The shading normals of triangle `t`'s three corners (mesh space: the angle is decided
    /// before an instance's scale, and a corner keeps its vertex normal's length): a vertex
    /// normal more than [`CREASE_DEGREES`] from the triangle's face normal is that (unit) face
    /// normal. Exporters that average normals across hard edges (CAD and IFC conversions,
    /// meshes smoothed without a crease angle) give a board's thin edge face vertex normals
    /// 45–55° off it, sweeping from one neighbour's direction to the other's within a texel:
    /// its irradiance would swing from sunlit to dark across a face that is flat. The face
    /// normal is taken on the side the vertex normals point to (a triangle wound against its
    /// normals keeps their side).
    ///
    /// # Panics
    /// If `t` is out of range.
    pub fn corner_normals(&self, t: usize) -> [Vec3; 3] {
        let [a, b, c] = self.triangle(t);
        let n = [self.normals[a], self.normals[b], self.normals[c]];
        let (pa, pb, pc) = (self.positions[a], self.positions[b], self.positions[c]);
        let mut face = (pb - pa).cross(pc - pa).normalize_or_zero();
        if face == Vec3::ZERO {
            return n;
        }
        if face.dot(n[0] + n[1] + n[2]) < 0.0 {
            face = -face;
        }
        let cos = CREASE_DEGREES.to_radians().cos();
        n.map(|v| {
            if v.normalize_or_zero().dot(face) < cos {
                face
            } else {
                v
            }
        })
    }

    /// The shading normal of triangle `t` at barycentric weights `bary` (of its second and
    /// third vertices), interpolated from [`Self::corner_normals`] (mesh space, not
    /// normalised).
    ///
    /// # Panics
    /// If `t` is out of range.
    pub fn shading_normal(&self, t: usize, bary: Vec2) -> Vec3 {
        let [na, nb, nc] = self.corner_normals(t);
        na * (1.0 - bary.x - bary.y) + nb * bary.x + nc * bary.y
    }

    /// The texture coordinates of both sets at barycentric weights `bary` (of the triangle's
    /// second and third vertices) of triangle `t`.
    ///
    /// # Panics
    /// If `t` is out of range.
    pub fn texcoords(&self, t: usize, bary: Vec2) -> TexCoords {
        let [a, b, c] = self.triangle(t);
        let at = |uv: &Option<Vec<Vec2>>| {
            uv.as_ref()
                .map(|uv| uv[a] * (1.0 - bary.x - bary.y) + uv[b] * bary.x + uv[c] * bary.y)
        };
        [at(&self.uv0), at(&self.uv1)]
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
        if !self.indices.len().is_multiple_of(3) {
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

#[cfg(test)]
mod tests {
    use super::*;

    /// One triangle in the plane z = 0 (face normal +Z) with the given vertex normals.
    fn triangle(normals: [Vec3; 3], wound_up: bool) -> Mesh {
        Mesh {
            positions: vec![Vec3::ZERO, Vec3::X, Vec3::Y],
            normals: normals.to_vec(),
            indices: if wound_up {
                vec![0, 1, 2]
            } else {
                vec![0, 2, 1]
            },
            ..Mesh::default()
        }
    }

    /// A board's edge face whose vertex normals were averaged with its neighbours across
    /// right angles (45° off) takes its face normal; a smooth cylinder's (30° off) keeps
    /// them; a triangle wound against its normals is creased on their side.
    #[test]
    fn normals_averaged_across_hard_edges_are_creased() {
        let averaged = Vec3::new(0.0, 1.0, 1.0).normalize();
        let smooth = Vec3::new(0.5, 0.0, 0.75f32.sqrt());
        let m = triangle([averaged, smooth, Vec3::Z], true);
        assert_eq!(m.corner_normals(0), [Vec3::Z, smooth, Vec3::Z]);
        let at = m.shading_normal(0, Vec2::new(0.5, 0.0));
        assert!((at - (Vec3::Z + smooth) * 0.5).length() < 1e-6, "{at:?}");
        let down = triangle([-averaged, -smooth, -Vec3::Z], false);
        // Corners in index order: vertices 0, 2, 1.
        assert_eq!(down.corner_normals(0), [-Vec3::Z, -Vec3::Z, -smooth]);
        // A degenerate triangle keeps its vertex normals.
        let mut flat = triangle([averaged; 3], true);
        flat.positions[2] = Vec3::X * 2.0;
        assert_eq!(flat.corner_normals(0), [averaged; 3]);
    }
}
