//! # lightbake
//!
//! An engine-free lightmap baker. A [`Scene`] (imported from glTF with [`import_gltf`], or
//! built in code) is baked with [`bake()`] (or, set up with [`BakeBuilder`], with previews,
//! in the background as a [`BakeHandle`], split across processes, or over a subset of the
//! texels) into HDR
//! lightmap pages with direct and interreflected light, and [`write_outputs`] writes them with
//! a baked glTF (`TEXCOORD_1`), a manifest and a report:
//!
//! ```no_run
//! use lightbake::{BakeSettings, LightConvention, Progress, import_gltf, write_outputs};
//!
//! let imported = import_gltf("assets/cornell_box.gltf".as_ref(), LightConvention::GltfSpec)?;
//! let settings = BakeSettings::medium();
//! let out = lightbake::bake(&imported.scene, &settings, &Progress::new())?;
//! write_outputs("baked".as_ref(), &out, &imported.scene, Some(&imported.source), &settings)?;
//! println!("{}", out.report.table());
//! # Ok::<(), lightbake::BakeError>(())
//! ```
//!
//! Units: metres; glTF / Bevy light units (candela, lux, nits). Texels store irradiance / π.
//! See `docs/units.md`.
//!
//! # Layers
//!
//! The modules form one order, and **each imports only modules listed before it** (the
//! workspace test `layers` checks this against the source):
//!
//! | # | module | what it holds |
//! |---|---|---|
//! | 1 | [`error`] | the user-facing error type |
//! | 1 | [`atomic`] | files staged to temporary names and renamed into place together |
//! | 1 | `color` | luminance, the sRGB transfer function |
//! | 1 | `form_factor` | Lambert's closed-form point-to-polygon form factor |
//! | 1 | `sampling` | hashes, Halton and Sobol' sequences, warps |
//! | 1 | [`settings`] | [`BakeSettings`], the presets and the setting enums |
//! | 1 | [`error_estimate`] | how a stage's error estimate is summarised and combined |
//! | 1 | [`stage`] | the pipeline's stages by name: [`Stage`] |
//! | 1 | [`progress`] | progress, cancellation and finished-stage counters |
//! | 2 | [`scene`] | meshes, instances, materials, textures, lights; glTF import and extras |
//! | 3 | `unwrap` | lightmap UVs (xatlas or the mesh's own) packed into atlas pages |
//! | 4 | `bvh` | closest-hit and any-hit ray queries |
//! | 5 | `raster` | texel patches, surface queries, validity, texel footprints |
//! | 6 | `lights` | the light interface, one file per kind (and emissive triangles) |
//! | 7 | `plan` | which stages the scene needs and why |
//! | 7 | `memory` | memory planning before allocating |
//! | 7 | `density` | texel density that follows the light: the direct-light pilot and each chart's scale |
//! | 7 | `context` | what every lighting pass reads |
//! | 7 | `runner` | how a pass runs its stages and where their work units run (the driver implements it) |
//! | 7 | [`incremental`] | what a bake keeps for the next one, what an edit changed, and how far it moves each texel's light |
//! | 8 | `direct` | direct light at every texel |
//! | 9 | `solve` | the matrix F and the linear solvers (pure linear algebra) |
//! | 10 | `radiosity` | nodes, basis, form factors, stochastic Jacobi, hierarchical radiosity, the radiosity pass |
//! | 11 | `vpl` | instant radiosity: walks, gather, bias compensation |
//! | 12 | [`lightmap`] | pages of E/π, filled and dilated |
//! | 13 | [`probes`] | irradiance volumes for dynamic objects, gathered from the lightmaps |
//! | 14 | [`report`] | what a bake records about itself |
//! | 15 | [`bake`](mod@bake) | the driver, [`BakeHandle`], the progressive previews and bakes split across processes |
//! | 16 | [`output`] | EXR/HDR/KTX2 + PNG, irradiance volumes, baked glTF, manifest, report; atomically |
//! | 17 | [`analysis`] | the reference path tracer, bakes scored against it at surface points, the convergence study |
//!
//! Modules without a link are the stages' internals: crate-private, and public with the
//! `internals` feature (for the benchmarks and the core's tests). The scenes of the core's
//! tests and of the shipped assets are behind the `testscenes` feature
//! (`lightbake::scene::testscenes`).

// Every type a public item names can be named by its users (the stages' types stay behind
// `internals`).
#![warn(unnameable_types)]

/// Declares stage modules: crate-private, or public with the `internals` feature.
macro_rules! internal {
    ($($name:ident),* $(,)?) => {
        $(
            #[cfg(feature = "internals")]
            pub mod $name;
            #[cfg(not(feature = "internals"))]
            pub(crate) mod $name;
        )*
    };
}

// 1. Foundations.
pub mod atomic;
pub mod error;
internal!(color, form_factor, sampling);
pub mod error_estimate;
pub mod progress;
pub mod settings;
pub mod stage;
// 2–7. The scene and what the lighting passes stand on.
pub mod scene;
internal!(
    unwrap, bvh, raster, lights, plan, memory, density, context, runner
);
pub mod incremental;
// 8–11. The lighting passes.
internal!(direct, solve, radiosity, vpl);
// 12–17. Results, the driver, writing, analysis.
pub mod analysis;
pub mod bake;
pub mod lightmap;
pub mod output;
pub mod probes;
pub mod report;

pub use bake::{BakeBuilder, BakeHandle, BakeOutput, SplitOutcome, bake};
pub use density::{DensityReport, MeshDensity};
pub use error::{BakeError, Result};
/// The `glam` the scene types use (re-exported so engine layers name the same version).
pub use glam;
pub use lightmap::LightmapPage;
pub use output::{Written, write_outputs};
pub use plan::texel_density as chosen_texel_density;
pub use progress::{Progress, ProgressSnapshot};
pub use report::BakeReport;
pub use scene::Scene;
pub use scene::gltf_import::{
    GltfSource, ImportOptions, ImportedScene, import_gltf, import_gltf_with,
};
pub use settings::{
    BakeSettings, Basis, ImageFormat, LightConvention, Method, OutputFormats, Quality, Sequence,
    SolverChoice,
};
pub use stage::{Stage, StageRun};
pub use unwrap::{BadLayout, InstanceRect, Layout, MeshUnwrap, PageSize, UvOrigin};
