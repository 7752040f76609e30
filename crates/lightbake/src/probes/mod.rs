//! Irradiance volumes for dynamic objects: a grid of probes over the baked region, each the
//! irradiance arriving from the six axis directions (an *ambient cube*, Mitchell 2006,
//! "Shading in Valve's Source engine", slide 27), read from the bake's own solution.
//!
//! A lightmap lights only the static meshes it was baked for; characters and props that move
//! take their diffuse indirect light from a volume instead (Bevy's `IrradianceVolume`). The
//! volume holds the light a moving object cannot get in real time: what the lit surfaces
//! reflect (their lightmaps), the light of emissive surfaces and the sky, and the direct light
//! of every light *excluded*, since the engine draws that on dynamic objects itself, with its
//! shadows.
//!
//! * [`headroom`]: how much room the level leaves a moving object above its floors (what the
//!   spacing resolves);
//! * [`grid`]: where one volume's probes go (its box, the spacing and why);
//! * [`regions`]: the volumes of a level, one per room, cut at its walls;
//! * `gather`: one probe's six sides from the solution (rays read the baked lightmaps);
//! * `bake`: the volume stage: every probe gathered, probes inside geometry moved to the
//!   nearest open point or filled from their neighbours, and the texture in Bevy's layout.

// One probe's gather and the volume stage read the stages' ray scene: public with the
// `internals` feature.
internal!(bake, gather);
pub mod grid;
pub mod headroom;
pub mod regions;
pub mod volume;

#[cfg(not(feature = "internals"))]
pub(crate) use bake::bake_volume;
#[cfg(feature = "internals")]
pub use bake::bake_volume;
pub use grid::{AutoSpacing, VolumeGrid};
pub use regions::plan_volumes;
pub use volume::{IrradianceVolume, ProbeState, VolumeStats, blend};
