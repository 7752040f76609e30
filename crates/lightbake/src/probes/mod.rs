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
//! * [`grid`]: where the probes go (the baked instances' bounds, the spacing and why);
//! * [`gather`]: one probe's six sides from the solution (rays read the baked lightmaps);
//! * [`volume`]: the volume stage: every probe gathered, probes inside geometry moved to the
//!   nearest open point or filled from their neighbours, and the texture in Bevy's layout.

pub mod gather;
pub mod grid;
pub mod volume;

pub use grid::VolumeGrid;
pub use volume::{IrradianceVolume, ProbeState, VolumeStats, bake_volume};
