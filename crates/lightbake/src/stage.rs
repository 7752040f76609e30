//! The pipeline's stages, by one name each: the plan lists them, the run times and counts
//! them, progress and previews name the running one, the report records them, a split bake's
//! part files are named after them, and the Bevy plugin's status shows them.
//!
//! A stage that a bake repeats (the radiosity rounds of a target error) is recorded once per
//! round: [`StageRun`] is a stage and its round.

use std::fmt;
use std::str::FromStr;

use serde::{Deserialize, Deserializer, Serialize, Serializer};

/// Declares the stages with their names, in pipeline order.
macro_rules! stages {
    ($($(#[$doc:meta])* $variant:ident = $name:literal,)*) => {
        /// One stage of the pipeline, in the order a bake runs them.
        #[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
        pub enum Stage {
            $($(#[$doc])* $variant,)*
        }

        impl Stage {
            /// Every stage, in pipeline order.
            pub const ALL: &'static [Stage] = &[$(Stage::$variant,)*];

            /// The stage's name, as the plan, the report and the progress show it.
            pub const fn name(self) -> &'static str {
                match self {
                    $(Stage::$variant => $name,)*
                }
            }
        }
    };
}

stages! {
    /// Which stages the scene needs ([`crate::report::BakePlan`]).
    Plan = "plan",
    /// Lightmap UVs: xatlas, or the meshes' own `TEXCOORD_1`, packed into pages.
    Unwrap = "unwrap",
    /// The texel density that follows the light: a direct-light pilot and a repack.
    Density = "density",
    /// The BVH for the ray queries.
    Bvh = "bvh",
    /// Texel patches made by another bake: a split bake's shard or merge reads prepare's; a
    /// bake that follows an edit keeps the earlier bake's when the geometry and its layout
    /// did not change.
    Patches = "patches",
    /// Texel patches rasterised from the unwrapped triangles.
    Raster = "raster",
    /// Texels moved out of geometry; those that cannot be are marked.
    Validity = "validity",
    /// The ray-tracing floor: the machine's closest-hit and any-hit rates.
    Calibrate = "calibrate",
    /// Direct light from the lights, the emissive surfaces and the sky.
    Direct = "direct",
    /// The indirect light as a whole, as the plan decides it: radiosity's stages (nodes to
    /// error estimate) or instant radiosity's ([`Stage::Vpl`]) run it.
    Indirect = "indirect",
    /// Instant radiosity: virtual point lights traced and gathered.
    Vpl = "vpl",
    /// Radiosity's nodes (the basis functions' support on the texel grid).
    Nodes = "nodes",
    /// The matrix solvers' transport matrix.
    Transport = "transport",
    /// A matrix solve.
    Solve = "solve",
    /// Hierarchical radiosity's coarse level, solved.
    CoarseSolve = "coarse solve",
    /// The adaptive final gather's pilot rays.
    GatherPilot = "gather pilot",
    /// The final gather of the coarse solution at every node.
    FinalGather = "final gather",
    /// The correction of the coarse level's light near geometry.
    Correction = "correction",
    /// The reflection near geometry the coarse level cannot resolve.
    Reflection = "reflection",
    /// The radiosity solution's error estimate.
    ErrorEstimate = "error estimate",
    /// The edge-aware filter of the sampling noise.
    Denoise = "denoise",
    /// The texel grid's own error, checked at points.
    GridError = "grid error",
    /// Texels next to geometry fitted to the visible surface.
    ContactFit = "contact fit",
    /// Invalid texels filled and the padding dilated.
    Dilate = "dilate",
    /// Both sides of every seam made to agree.
    Stitch = "stitch",
    /// The irradiance volume for dynamic objects.
    Volume = "volume",
    /// A bake with light groups relit from the cache: each group's cached pages weighted by
    /// the change of its emitters' light ([`crate::incremental::relight`]).
    Relight = "relight",
    /// Lightmaps, baked glTF, manifest and report written.
    Write = "write",
}

/// A part of a bake's input, as a bake that follows an edit tells edits apart
/// ([`crate::incremental::Edits::changed`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Input {
    /// The meshes' geometry and the instances' placement: what rays hit, and from which side
    /// (a material's two-sidedness).
    Geometry,
    /// The lightmap layout: pages, each instance's rectangle, each mesh's charts.
    Layout,
    /// What surfaces reflect: base colour, its texture, metalness.
    Albedo,
    /// What surfaces emit.
    Emission,
    /// The punctual and directional lights.
    Lights,
    /// The sky.
    Sky,
}

/// How a bake that follows an edit of a cached bake treats a stage's output.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Kept {
    /// Item by item (a split stage): each texel or node is computed again where the edit can
    /// move what it reads by more than a share of the bake's error, the rest keep their values.
    Items,
    /// Kept whole from the cache when nothing it reads changed, else run again whole.
    Whole,
    /// Its structure kept from the cache when the geometry and the layout did not change and
    /// brought up to date with what did (the coarse level: its cut and matrix kept, its
    /// first bounce updated where the reflected direct light changed; the nodes: their basis
    /// areas kept, their albedo made again; the contact fit: its samples kept, its fit made
    /// again); else run again whole.
    Updated,
    /// Kept from the cache whatever the edit (the texel density: the layout stays stable;
    /// `--full` decides it again).
    Pinned,
    /// Run again whole in every bake: its output is not kept in the cache.
    Again,
}

/// What a stage reads: parts of the input and earlier stages' outputs, and how a bake that
/// follows an edit treats its own output. The driver orders the stages; this table is what
/// an incremental bake decides from ([`Stage::changed_by`]) and what its plan lists.
#[derive(Clone, Copy, Debug)]
pub struct Reads {
    /// The parts of the input it reads itself.
    pub inputs: &'static [Input],
    /// The earlier stages whose outputs it reads.
    pub stages: &'static [Stage],
    /// What a bake that follows an edit does with it.
    pub kept: Kept,
}

impl Stage {
    /// What the stage reads, and how a bake that follows an edit treats it.
    pub const fn reads(self) -> Reads {
        use Input::{Albedo, Emission, Geometry, Layout, Lights, Sky};
        const LIGHT: &[Input] = &[Geometry, Lights, Sky, Emission];
        const ALL: &[Input] = &[Geometry, Layout, Albedo, Emission, Lights, Sky];
        let (inputs, stages, kept): (&[Input], &[Stage], Kept) = match self {
            Stage::Plan | Stage::Indirect => (ALL, &[], Kept::Again),
            Stage::Unwrap => (&[Geometry], &[], Kept::Items),
            Stage::Density => (LIGHT, &[Stage::Unwrap], Kept::Pinned),
            Stage::Bvh | Stage::Calibrate => (&[Geometry], &[], Kept::Again),
            Stage::Raster | Stage::Patches => (&[Geometry, Layout], &[], Kept::Whole),
            Stage::Validity => (&[Geometry, Layout], &[Stage::Raster], Kept::Whole),
            Stage::Direct => (LIGHT, &[Stage::Validity], Kept::Items),
            Stage::Vpl => (ALL, &[Stage::Validity], Kept::Again),
            Stage::Nodes => (&[Albedo], &[Stage::Validity], Kept::Updated),
            Stage::Transport => (&[Geometry], &[Stage::Nodes], Kept::Again),
            Stage::Solve => (&[], &[Stage::Transport, Stage::Direct], Kept::Again),
            Stage::CoarseSolve => (&[Geometry], &[Stage::Nodes, Stage::Direct], Kept::Updated),
            Stage::GatherPilot => (
                &[Geometry],
                &[Stage::Nodes, Stage::Direct, Stage::CoarseSolve],
                Kept::Items,
            ),
            Stage::FinalGather => (
                &[Geometry],
                &[Stage::Direct, Stage::CoarseSolve, Stage::GatherPilot],
                Kept::Items,
            ),
            Stage::Correction => (
                &[Geometry],
                &[Stage::CoarseSolve, Stage::FinalGather],
                Kept::Items,
            ),
            Stage::Reflection => (&[Geometry], &[Stage::Correction], Kept::Items),
            Stage::ErrorEstimate => (
                &[Geometry],
                &[Stage::Direct, Stage::Reflection, Stage::Solve],
                Kept::Again,
            ),
            Stage::Denoise => (
                &[Geometry],
                &[Stage::Direct, Stage::Reflection, Stage::Solve, Stage::Vpl],
                Kept::Again,
            ),
            Stage::GridError => (LIGHT, &[Stage::Direct], Kept::Again),
            Stage::ContactFit => (&[Geometry], &[Stage::Denoise], Kept::Updated),
            Stage::Dilate => (&[Layout], &[Stage::ContactFit], Kept::Again),
            Stage::Stitch => (&[Layout], &[Stage::Dilate], Kept::Again),
            Stage::Volume => (&[Geometry], &[Stage::Stitch], Kept::Again),
            Stage::Relight => (&[Lights, Sky], &[Stage::Stitch], Kept::Again),
            Stage::Write => (&[], &[Stage::Stitch, Stage::Volume], Kept::Again),
        };
        Reads {
            inputs,
            stages,
            kept,
        }
    }

    /// Whether an edit that changed the parts `changed` of the input can change this
    /// stage's output: it reads one of them, or an earlier stage's output that can change.
    pub fn changed_by(self, changed: &[Input]) -> bool {
        let r = self.reads();
        r.inputs.iter().any(|i| changed.contains(i))
            || r.stages.iter().any(|s| s.changed_by(changed))
    }

    /// The stage of the plan that runs this one: [`Stage::Indirect`] for radiosity's and
    /// instant radiosity's stages, the stage itself otherwise.
    pub const fn planned_as(self) -> Stage {
        match self {
            Stage::Vpl
            | Stage::Nodes
            | Stage::Transport
            | Stage::Solve
            | Stage::CoarseSolve
            | Stage::GatherPilot
            | Stage::FinalGather
            | Stage::Correction
            | Stage::Reflection
            | Stage::ErrorEstimate => Stage::Indirect,
            s => s,
        }
    }
}

impl fmt::Display for Stage {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// A name that is not a stage's.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct UnknownStage(pub String);

impl fmt::Display for UnknownStage {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let names: Vec<&str> = Stage::ALL.iter().map(|s| s.name()).collect();
        write!(
            f,
            "'{}' is not a stage (stages: {})",
            self.0,
            names.join(", ")
        )
    }
}

impl std::error::Error for UnknownStage {}

impl FromStr for Stage {
    type Err = UnknownStage;

    fn from_str(s: &str) -> Result<Self, Self::Err> {
        Stage::ALL
            .iter()
            .copied()
            .find(|st| st.name() == s)
            .ok_or_else(|| UnknownStage(s.to_string()))
    }
}

impl Serialize for Stage {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        s.serialize_str(self.name())
    }
}

impl<'de> Deserialize<'de> for Stage {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        let name = String::deserialize(d)?;
        name.parse().map_err(serde::de::Error::custom)
    }
}

/// One run of a stage: the stage and its round (1 for the first; a target error repeats the
/// radiosity stages).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub struct StageRun {
    /// The stage.
    pub stage: Stage,
    /// Its round, 1 for the first.
    pub round: u32,
}

impl StageRun {
    /// The first (usually only) run of `stage`.
    pub const fn first(stage: Stage) -> Self {
        Self { stage, round: 1 }
    }
}

impl From<Stage> for StageRun {
    fn from(stage: Stage) -> Self {
        Self::first(stage)
    }
}

impl fmt::Display for StageRun {
    /// The stage's name, with ` #round` after the first round.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        if self.round > 1 {
            write!(f, "{} #{}", self.stage.name(), self.round)
        } else {
            f.write_str(self.stage.name())
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_are_unique_and_parse_back() {
        for (i, a) in Stage::ALL.iter().enumerate() {
            assert_eq!(a.name().parse::<Stage>(), Ok(*a));
            assert!(Stage::ALL[i + 1..].iter().all(|b| b.name() != a.name()));
        }
        assert!("indirekt".parse::<Stage>().is_err());
        let json = serde_json::to_string(&Stage::CoarseSolve).unwrap();
        assert_eq!(json, "\"coarse solve\"");
        assert_eq!(
            serde_json::from_str::<Stage>(&json).unwrap(),
            Stage::CoarseSolve
        );
    }

    #[test]
    fn a_stage_reads_only_stages_before_it_and_follows_what_it_reads() {
        for &s in Stage::ALL {
            for &earlier in s.reads().stages {
                assert!(earlier < s, "{s} reads {earlier}, which runs after it");
            }
        }
        // An edit of the light alone leaves the texel patches and the nodes as they were,
        // and reaches the gathers through the direct light.
        let light = [Input::Lights];
        assert!(!Stage::Validity.changed_by(&light));
        assert!(!Stage::Nodes.changed_by(&light));
        assert!(Stage::FinalGather.changed_by(&light));
        assert!(Stage::Stitch.changed_by(&light));
        // A new albedo reaches the gathers through the nodes, not the direct light.
        let albedo = [Input::Albedo];
        assert!(!Stage::Direct.changed_by(&albedo));
        assert!(Stage::Correction.changed_by(&albedo));
        // Moved geometry changes everything that reads it.
        assert!(Stage::Validity.changed_by(&[Input::Geometry]));
        assert!(Stage::Validity.changed_by(&[Input::Layout]));
    }

    #[test]
    fn rounds_after_the_first_are_numbered() {
        let run = StageRun {
            stage: Stage::FinalGather,
            round: 2,
        };
        assert_eq!(run.to_string(), "final gather #2");
        assert_eq!(StageRun::first(Stage::Direct).to_string(), "direct");
        assert_eq!(Stage::CoarseSolve.planned_as(), Stage::Indirect);
        assert_eq!(Stage::Denoise.planned_as(), Stage::Denoise);
    }
}
