//! `manifest.json`: what a game needs to attach the lightmaps — per page its files, per baked
//! instance its page, image and Bevy `uv_rect`.

use serde::Serialize;

use crate::bake::BakeOutput;
use crate::scene::Scene;
use crate::unwrap::UvOrigin;

/// Version of the manifest format.
pub const MANIFEST_VERSION: u32 = 1;

/// Files of one atlas page, relative to the output directory.
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct PageFiles {
    /// Page index.
    pub index: u32,
    /// Texels across.
    pub width: u32,
    /// Texels down.
    pub height: u32,
    /// OpenEXR file, if written.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub exr: Option<String>,
    /// Radiance HDR file, if written.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub hdr: Option<String>,
    /// KTX2 file, if written.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub ktx2: Option<String>,
    /// KTX2 file of BC6H blocks, if written.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub ktx2_bc6h: Option<String>,
    /// Tonemapped PNG preview, if written.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub preview: Option<String>,
}

impl PageFiles {
    /// The file a game should load (EXR, else KTX2, else HDR, else BC6H).
    pub fn primary(&self) -> Option<&str> {
        self.exr
            .as_deref()
            .or(self.ktx2.as_deref())
            .or(self.hdr.as_deref())
            .or(self.ktx2_bc6h.as_deref())
    }

    /// The BC6H file when one was written besides [`Self::primary`] (which names it only when
    /// it is the only one).
    pub fn bc6h_besides_primary(&self) -> Option<&str> {
        let bc6h = self.ktx2_bc6h.as_deref()?;
        (self.primary() != Some(bc6h)).then_some(bc6h)
    }
}

/// One baked instance in the manifest.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct ManifestInstance {
    /// Instance name (glTF node name, `#primitive` appended when the mesh has several).
    pub name: String,
    /// glTF node index.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub node: Option<usize>,
    /// glTF mesh index.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub mesh: Option<usize>,
    /// glTF primitive index.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub primitive: Option<usize>,
    /// Page index.
    pub page: u32,
    /// The page's primary image, relative to the output directory.
    pub image: String,
    /// Bevy's `Lightmap::uv_rect`: [min u, min v, max u, max v] on the page.
    pub uv_rect: [f32; 4],
    /// The rectangle in texels: [x, y, width, height].
    pub rect: [u32; 4],
    /// Texels per metre achieved on the mesh's largest instance.
    pub texel_density: f32,
    /// `xatlas` or `existing` (the mesh's own TEXCOORD_1).
    pub uv_source: UvOrigin,
}

/// One irradiance volume in the manifest (the same entry the baked glTF's scene extras
/// carry).
pub use crate::scene::extras::VolumeExtras as ManifestVolume;

/// `manifest.json`: what a game needs to attach the lightmaps.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Manifest {
    /// Always `lightbake-manifest`.
    pub format: &'static str,
    /// [`MANIFEST_VERSION`].
    pub version: u32,
    /// The source scene file name.
    pub scene: String,
    /// The baked glTF, relative to the output directory.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub baked_gltf: Option<String>,
    /// What the texels hold.
    pub stored_quantity: &'static str,
    /// Pages.
    pub pages: Vec<PageFiles>,
    /// Baked instances.
    pub instances: Vec<ManifestInstance>,
    /// Irradiance volumes for dynamic objects (none unless asked for).
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub irradiance_volumes: Vec<ManifestVolume>,
    /// What the volumes' voxels hold (when there are volumes).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub volume_stored_quantity: Option<&'static str>,
    /// The light groups, when the bake has any: each one's lightmaps, whose sum is `pages`.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub light_groups: Vec<ManifestGroup>,
}

/// One light group in the manifest: its name, members, page files (in the order and sizes of
/// the bake's pages) and volume files.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct ManifestGroup {
    /// The group's name.
    pub name: String,
    /// What it holds: `light NAME`, `material NAME`, `sky`.
    pub members: Vec<String>,
    /// Its pages.
    pub pages: Vec<PageFiles>,
    /// Its irradiance volumes, relative to the output directory.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub irradiance_volumes: Vec<String>,
}

/// The volumes of a bake, as the manifest and the baked glTF list them.
pub fn volumes(output: &BakeOutput) -> Vec<ManifestVolume> {
    output
        .irradiance_volumes
        .iter()
        .enumerate()
        .map(|(i, v)| {
            let (center, size) = v.grid.centre_and_size();
            ManifestVolume {
                image: volume_file(i),
                center: center.to_array(),
                size: size.to_array(),
                rotation: v.grid.rotation.to_array(),
                falloff: v.grid.falloff.to_array(),
                resolution: v.grid.resolution.to_array(),
                intensity: 1.0,
            }
        })
        .collect()
}

/// File of irradiance volume `i`, relative to the output directory.
pub fn volume_file(i: usize) -> String {
    format!("irradiance_volumes/volume_{i}.ktx2")
}

/// File of light group `group`'s irradiance volume `i`, relative to the output directory.
pub fn group_volume_file(group: &str, i: usize) -> String {
    format!("irradiance_volumes/groups/{group}/volume_{i}.ktx2")
}

/// The light groups of a bake with their files (`pages`: each group's page files).
pub fn groups(output: &BakeOutput, pages: &[Vec<PageFiles>]) -> Vec<ManifestGroup> {
    (output.groups.iter().zip(pages))
        .map(|(g, files)| ManifestGroup {
            name: g.name.clone(),
            members: g.report.members.clone(),
            pages: files.clone(),
            irradiance_volumes: (g.irradiance_volumes.iter().enumerate())
                .map(|(i, _)| group_volume_file(&g.name, i))
                .collect(),
        })
        .collect()
}

/// The manifest of a bake.
pub fn manifest(
    output: &BakeOutput,
    original: &Scene,
    (pages, group_pages): (&[PageFiles], &[Vec<PageFiles>]),
    baked_gltf: Option<String>,
) -> Manifest {
    let mut instances = Vec::new();
    for (i, inst) in original.instances.iter().enumerate() {
        let Some(rect) = output.layout.instances[i] else {
            continue;
        };
        let unwrap = output.layout.meshes[inst.mesh]
            .as_ref()
            .expect("rect implies unwrap");
        let source = original.meshes[inst.mesh].source;
        instances.push(ManifestInstance {
            name: inst.name.clone(),
            node: inst.gltf_node,
            mesh: source.map(|s| s.mesh),
            primitive: source.map(|s| s.primitive),
            page: rect.page,
            image: pages[rect.page as usize]
                .primary()
                .unwrap_or_default()
                .to_string(),
            uv_rect: rect.uv_rect(output.layout.pages[rect.page as usize]),
            rect: [rect.x, rect.y, rect.width, rect.height],
            texel_density: unwrap.texels_per_metre,
            uv_source: unwrap.origin,
        });
    }
    Manifest {
        format: "lightbake-manifest",
        version: MANIFEST_VERSION,
        scene: original.name.clone(),
        baked_gltf,
        stored_quantity: "irradiance / pi (lux / pi), linear RGB; Bevy: Lightmap with lightmap_exposure = 1",
        pages: pages.to_vec(),
        instances,
        irradiance_volumes: volumes(output),
        volume_stored_quantity: (!output.irradiance_volumes.is_empty()).then_some(
            "irradiance / pi from each side (-X, +X, -Y, +Y, -Z, +Z), without the lights' direct light; Bevy: IrradianceVolume with intensity 1",
        ),
        light_groups: groups(output, group_pages),
    }
}
