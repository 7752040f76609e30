//! # lightbake
//!
//! An engine-free lightmap baker. A [`Scene`] (imported from glTF with
//! [`scene::gltf_import::import_gltf`], or built in code) goes through the pipeline in the
//! order of the modules below, and comes out as HDR lightmap pages, a baked glTF with
//! `TEXCOORD_1`, a manifest and a report:
//!
//! 1. [`scene`]: meshes, instances, materials, lights, sky; glTF import.
//! 2. [`plan`]: which stages this scene needs, and why the others are skipped.
//! 3. [`unwrap`]: lightmap UVs with xatlas (or the mesh's own), packed into atlas pages.
//! 4. [`raster`]: every covered texel becomes a patch; patches inside geometry are fixed.
//! 5. [`bvh`]: closest-hit and any-hit ray queries (obvhs PLOC build, our four-wide BVH).
//! 6. [`direct`]: point, spot, directional, sky and emissive-surface light with shadow rays.
//! 7. [`transport`], [`solve`], [`indirect`]: radiosity over the texel nodes — form factors
//!    (Monte Carlo, hemicube, closed form) and the solver family.
//!    [`vpl`]: instant radiosity — quasi-random walks leave virtual point lights, gathered
//!    into the texels (methods `vpl` and `hybrid`).
//! 8. [`lightmap`]: pages of E/π, invalid texels filled, padding dilated.
//! 9. [`output`]: EXR/HDR/KTX2 + PNG preview, baked glTF, manifest, report; atomically.
//!
//! ```no_run
//! use lightbake::{bake, settings::BakeSettings, progress::Progress};
//! use lightbake::scene::gltf_import::import_gltf;
//! use lightbake::settings::LightConvention;
//!
//! let imported = import_gltf("assets/cornell_box.gltf".as_ref(), LightConvention::GltfSpec)?;
//! let settings = BakeSettings::medium();
//! let out = bake(&imported.scene, &settings, &Progress::new())?;
//! lightbake::output::write_outputs("baked".as_ref(), &out, &imported.scene, Some(&imported.source), &settings)?;
//! println!("{}", out.report.table());
//! # Ok::<(), lightbake::BakeError>(())
//! ```
//!
//! Units: metres; glTF / Bevy light units (candela, lux, nits). Texels store irradiance / π.
//! See `docs/units.md`.

pub mod bake;
pub mod bvh;
pub mod direct;
pub mod error;
pub mod estimate;
pub mod indirect;
pub mod lightmap;
pub mod memory;
pub mod output;
pub mod plan;
pub mod progress;
pub mod raster;
pub mod reference;
pub mod report;
pub mod sampling;
pub mod scene;
pub mod settings;
pub mod solve;
pub mod study;
pub mod transport;
pub mod unwrap;
pub mod vpl;

pub use bake::{BakeOutput, bake};
pub use error::{BakeError, Result};
/// The `glam` the scene types use (re-exported so engine layers name the same version).
pub use glam;
pub use scene::Scene;
pub use settings::BakeSettings;
