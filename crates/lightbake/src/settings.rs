//! Bake settings: one plain struct, each field with its unit, range and default, plus the
//! named quality presets the CLI's `--quality` and the Bevy plugin map onto.

use serde::{Deserialize, Serialize};

use crate::error::{BakeError, Result};
pub use crate::sampling::Sequence;

/// How light is computed.
#[cfg_attr(feature = "clap", derive(clap::ValueEnum))]
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Method {
    /// Direct light only: punctual lights, the sun, emissive surfaces and the sky, each with
    /// shadow rays. Interreflected light is not computed.
    Direct,
    /// Direct light plus interreflection by radiosity over the texels (the default).
    #[default]
    Radiosity,
    /// Instant radiosity: all light from virtual point lights, the light sources themselves
    /// as the first generation.
    Vpl,
    /// Direct light exact, indirect light from virtual point lights.
    Hybrid,
}

/// Which solver to use.
#[cfg_attr(feature = "clap", derive(clap::ValueEnum))]
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum SolverChoice {
    /// Chosen from the scene and stated in the plan: dense LU for small systems, the full
    /// matrix with BiCGStab up to `AUTO_MATRIX_NODES` nodes (Gauss-Seidel when BiCGStab's
    /// vectors do not fit beside the matrix), hierarchical beyond, or when the matrix does
    /// not fit its budget.
    #[default]
    Auto,
    /// Hierarchical: a coarse solve over texel clusters, refined where it is too coarse,
    /// then a final gather per texel; memory linear in the texels (no full matrix).
    Hierarchical,
    /// Jacobi gathering.
    Jacobi,
    /// Gauss-Seidel gathering.
    GaussSeidel,
    /// Progressive refinement (Southwell shooting).
    Shooting,
    /// Stochastic Jacobi: matrix-free, for scenes whose transport matrix does not fit.
    StochasticJacobi,
    /// BiCGStab on the unsymmetric system; for stiff scenes (albedo near 1).
    Krylov,
    /// Conjugate gradients on the reciprocity-symmetrised system.
    KrylovCg,
    /// Dense LU (small systems only, up to 4096 nodes).
    Direct,
}

impl SolverChoice {
    /// The name used on the command line and in reports.
    pub fn name(self) -> &'static str {
        match self {
            Self::Auto => "auto",
            Self::Hierarchical => "hierarchical",
            Self::Jacobi => "jacobi",
            Self::GaussSeidel => "gauss-seidel",
            Self::Shooting => "shooting",
            Self::StochasticJacobi => "stochastic-jacobi",
            Self::Krylov => "krylov",
            Self::KrylovCg => "krylov-cg",
            Self::Direct => "direct",
        }
    }

    /// Whether the solver needs the full transport matrix (one row per node).
    pub fn needs_matrix(self) -> bool {
        !matches!(self, Self::StochasticJacobi | Self::Hierarchical)
    }
}

/// How radiosity is reconstructed between texel centres.
#[cfg_attr(feature = "clap", derive(clap::ValueEnum))]
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Basis {
    /// Bilinear over the four surrounding texel centres (what the GPU shows).
    #[default]
    Linear,
    /// Constant over each texel.
    Constant,
}

/// Deepest reflection an instant-radiosity walk can follow: each reflection takes two of the
/// 64 dimensions of a particle's number sequence, after the six of its start.
pub const MAX_VPL_DEPTH: u32 = 29;

/// Named quality presets (`--quality preview|medium|high`).
#[cfg_attr(feature = "clap", derive(clap::ValueEnum))]
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Quality {
    /// Fast look: low density, few samples.
    Preview,
    /// The default.
    #[default]
    Medium,
    /// Final bakes.
    High,
}

/// An HDR lightmap file format.
#[cfg_attr(feature = "clap", derive(clap::ValueEnum))]
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum ImageFormat {
    /// OpenEXR, RGB half float, ZIP compressed.
    Exr,
    /// Radiance RGBE.
    Hdr,
    /// KTX2, `R16G16B16A16_SFLOAT` (Bevy loads it as `Rgba16Float`).
    Ktx2,
}

/// Which lightmap files are written per atlas page.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct OutputFormats {
    /// OpenEXR, RGB half float, ZIP compressed (`lightmap_N.exr`). Default on.
    pub exr: bool,
    /// Radiance RGBE (`lightmap_N.hdr`). Default off.
    pub hdr: bool,
    /// KTX2, `R16G16B16A16_SFLOAT`, uncompressed (`lightmap_N.ktx2`). Default off.
    pub ktx2: bool,
    /// A tonemapped sRGB PNG to look at (`lightmap_N.preview.png`). Default on.
    pub png_preview: bool,
}

impl OutputFormats {
    /// The HDR formats in `hdr`, plus the PNG preview when `png_preview` is set.
    pub fn of(hdr: &[ImageFormat], png_preview: bool) -> Self {
        Self {
            exr: hdr.contains(&ImageFormat::Exr),
            hdr: hdr.contains(&ImageFormat::Hdr),
            ktx2: hdr.contains(&ImageFormat::Ktx2),
            png_preview,
        }
    }
}

impl Default for OutputFormats {
    fn default() -> Self {
        Self {
            exr: true,
            hdr: false,
            ktx2: false,
            png_preview: true,
        }
    }
}

/// How punctual-light parameters the glTF leaves open are read.
///
/// The glTF specification says `KHR_lights_punctual` colours are linear and a light without
/// `range` reaches infinitely far. Bevy 0.19's glTF loader reads the colour as sRGB and gives
/// such a light a range of 20 m. See `docs/units.md`.
#[cfg_attr(feature = "clap", derive(clap::ValueEnum))]
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum LightConvention {
    /// Follow the glTF specification (default for the CLI): linear light colours, no range =
    /// infinite.
    #[default]
    #[cfg_attr(feature = "clap", value(name = "gltf"))]
    GltfSpec,
    /// Match what Bevy 0.19's glTF loader does, so a baked light equals Bevy's real-time one:
    /// sRGB light colours, no range = 20 m.
    #[cfg_attr(feature = "clap", value(name = "bevy"))]
    BevyGltfLoader,
}

/// Everything that steers a bake. Build it from a preset and change fields:
///
/// ```
/// use lightbake::settings::{BakeSettings, Quality};
/// let mut s = BakeSettings::preset(Quality::High);
/// s.texel_density = Some(64.0);
/// assert!(s.validate().is_ok());
/// ```
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct BakeSettings {
    /// How light is computed. Default [`Method::Radiosity`].
    pub method: Method,
    /// Radiosity solver. Default [`SolverChoice::Auto`] (stated in the plan).
    pub solver: SolverChoice,
    /// Radiosity basis over the texel grid. Default [`Basis::Linear`].
    pub basis: Basis,
    /// Monte Carlo form-factor rays per texel node: a row of the full matrix, or the final
    /// gather of the hierarchical solve. Range 1..=65 536.
    /// Default 128 (medium), 32 (preview), 256 (high: four times the texels, each with twice
    /// the rays).
    pub transport_rays: u32,
    /// The hierarchical solve's final gather shares its rays out by each node's noise in a
    /// pilot of a quarter of them (`radiosity::ray_allocation`): the same rays in all, more
    /// where the gathered light is noisy. Off: `transport_rays` at every node (the rays of
    /// the full matrix's rows). Needs `transport_rays` ≥ 16. Default on.
    pub adaptive_gather: bool,
    /// Hierarchical solve: edge of the first cut's cells, texels (a power of two,
    /// 1..=256); refinement splits them where the coarse solution is too coarse.
    /// Default 16 (preview), 8 (medium, high).
    pub cluster_texels: u32,
    /// Hierarchical solve: form-factor rays per cell of the coarse level (shared out over its
    /// texels, at least one each). Range 1..=65 536. Default 64 (preview), 128 (medium,
    /// high).
    pub cluster_rays: u32,
    /// Hierarchical solve: refine the coarse level until the light its cells miss (the RMS
    /// over the surface of the spread between a cell's quadrants, reflected) is at most this
    /// fraction of the RMS irradiance. Range (0, 1). Default 0.02 (preview), 0.01 (medium),
    /// 0.005 (high).
    pub cluster_tolerance: f64,
    /// Largest transport matrix plus the solver's working memory beside it
    /// (`SolverChoice::working_bytes`), MiB; beyond it `Auto` takes the hierarchical solve
    /// (which must fit it too) and the matrix solvers refuse. The smaller of this and
    /// what [`Self::memory_budget_mib`] leaves beside the rest of the bake applies.
    /// Default 4096.
    pub transport_budget_mib: u64,
    /// Target relative error of the radiosity solve. Since ‖(I − ρF)⁻¹‖∞ ≤ 1/(1 − ρ_max),
    /// solvers stop at the relative residual ‖S + ρFB − B‖/‖S‖ ≤ target·(1 − ρ_max).
    /// Range (0, 1). Default 10⁻³.
    pub solver_tolerance: f64,
    /// Give the solver up after this many iterations (sweeps). Default 20 000.
    pub max_solver_iterations: u32,
    /// Stochastic Jacobi: rays in its first iteration per node. Default 64.
    pub stochastic_rays_per_node: u32,
    /// Instant radiosity: particles started from the lights (N); about N/(1 − ρ̄) VPLs result.
    /// Range 1..=10⁷. Default 1024 (medium), 256 (preview), 4096 (high).
    pub vpl_particles: u32,
    /// Instant radiosity: choose N to fit this many seconds of gathering instead (measured
    /// against a pilot). Default none.
    pub vpl_time_budget_s: Option<f64>,
    /// Instant radiosity: the number pattern of the walks. Default
    /// [`Sequence::ScrambledHalton`] (plain Halton converges as fast but its higher bases are
    /// correlated at small N).
    pub vpl_sequence: Sequence,
    /// Instant radiosity: VPLs closer than this (m) are clamped (G ≤ 1/d²). Default 2% of the
    /// scene's diagonal.
    pub vpl_clamp_distance: Option<f32>,
    /// Instant radiosity: restore the clamped energy (Kollig & Keller 2004). Default off.
    pub vpl_bias_compensation: bool,
    /// Instant radiosity: rays per texel of the bias compensation. Default 64.
    pub vpl_compensation_rays: u32,
    /// Instant radiosity: deepest reflection followed (≤ 29). Default 16.
    pub vpl_max_depth: u32,
    /// Lightmap texels per metre of world-space surface (per axis; per scene unit for a scene
    /// not in metres). Range (0, 10⁹]; the memory plan refuses what does not fit. Default
    /// none: the density is chosen so the baked surfaces get about [`Self::texel_budget`]
    /// texels, whatever the scene's unit. When set, it wins over the scene's own hint
    /// (`scene.extras.lightbake.texel_density`) and over the budget; a node's
    /// `texel_density_scale` multiplies it either way.
    pub texel_density: Option<f32>,
    /// Take the scene's `texel_density` hint when it has one and `texel_density` is not set.
    /// Default true.
    pub texel_density_from_scene: bool,
    /// Covered lightmap texels to aim for when the density is chosen automatically (no
    /// `texel_density` and no scene hint): density = √(budget / Σ baked area × scale²).
    /// Range 1 000..=100 000 000. Default 65 536 (preview), 262 144 (medium), 1 048 576 (high).
    pub texel_budget: u64,
    /// When the density comes from [`Self::texel_budget`], share the budget out by a pilot of
    /// the direct light: charts whose light varies most within a texel get up to twice the
    /// density, flat ones down to half, the total kept (`crate::density`; the plan and the
    /// report's `density` say each chart's scale). Default true.
    pub adaptive_density: bool,
    /// Empty texels kept between charts and between atlas rectangles, filled by dilation so
    /// bilinear and bicubic sampling never read unset texels. Range 1..=16. Default 2.
    pub padding: u32,
    /// Largest atlas page, in texels per side. More pages are made when one is not enough.
    /// Range 64..=16384. Default 2048.
    pub max_page_size: u32,
    /// Samples per texel for direct light: each is a point in the texel's footprint and one
    /// sample of every light, so shadow edges are antialiased. Range 1..=4096.
    /// Default 32 (medium), 8 (preview), 64 (high); chosen from the convergence study
    /// (`docs/convergence.md`).
    pub samples_per_texel: u32,
    /// Cosine-distributed rays per texel towards the uniform sky (only when the sky is not
    /// black). Range 1..=65 536. Default 64 (medium), 16 (preview), 128 (high).
    pub sky_samples: u32,
    /// Emitters (emissive triangles) up to which each texel evaluates the closed-form,
    /// unoccluded point-to-polygon irradiance and uses the shadow rays only for the visible
    /// fraction (a ratio estimator, exact where the emitter is fully visible). Above it the
    /// emitters are sampled by power. Default 256.
    pub max_closed_form_emitters: u32,
    /// Unwrap every mesh again with xatlas, even those that carry their own `TEXCOORD_1`.
    /// Default false.
    pub reunwrap: bool,
    /// Fit the texels next to geometry so that the lightmap's bilinear reconstruction is right
    /// on the visible surface (a floor texel whose centre is under a thin wall, a texel
    /// under a rug, padding beside a contact; `lightmap::contacts`). Default true.
    pub contact_fit: bool,
    /// Filter each chart's texels with an edge-aware denoiser, as strongly as each texel's
    /// estimated noise warrants, and carry the error estimate through it
    /// (`lightmap::denoise`). Default off (preview), on (medium, high).
    pub denoise: bool,
    /// The denoiser's radius, texels. Range 1..=8. Default 3.
    pub denoise_radius: u32,
    /// Make the two sides of every seam (a surface split between charts) agree after
    /// bilinear filtering, by a least-squares stitch of the texels along it
    /// (`lightmap::stitch`). Default true.
    pub stitch_seams: bool,
    /// Also bake an irradiance volume for dynamic objects ([`crate::probes`]): a grid of
    /// probes over the baked instances, each the light from the six axis directions read from
    /// the lightmaps (without the direct light of the lights, which the engine draws on
    /// dynamic objects itself), written as `irradiance_volumes/volume_0.ktx2` in the layout
    /// Bevy's `IrradianceVolume` reads. Default false.
    pub irradiance_volume: bool,
    /// Distance between the volume's probes, m (per scene unit). Default none: 16 lightmap
    /// texels at the bake's density, widened so the volume has at most 65 536 probes (the
    /// plan says so). An explicit spacing giving over 2²⁰ probes is refused.
    pub probe_spacing: Option<f32>,
    /// Rays per probe of the irradiance volume (plus a quarter as many samples of emissive
    /// surfaces). Range 1..=65 536. Default 256 (preview), 512 (medium), 1024 (high).
    pub probe_rays: u32,
    /// Seed of every Monte Carlo estimate (numbers are indexed by texel, sample and this seed,
    /// never by thread). The validity pass, which decides geometry (which texels are inside
    /// solids and where their points move), uses a fixed seed instead, so two seeds differ by
    /// noise alone. Default 0.
    pub seed: u32,
    /// Worker threads; 0 uses every core. The result does not depend on it. Default 0.
    pub threads: usize,
    /// Refuse a bake whose estimated memory exceeds this many MiB; the transport matrix and
    /// the solver are planned within what the rest of the bake leaves of it. Default 8192.
    pub memory_budget_mib: u64,
    /// Refuse a bake the plan estimates to trace more rays than this
    /// ([`crate::report::BakePlan`]'s estimate: texels × rays per texel, probes × rays per
    /// probe). Range 10⁶..=10¹⁵. Default 10¹¹ (about three hours at 10 Mrays/s).
    pub max_rays: u64,
    /// Target relative RMS error of the lightmap (e.g. 0.02 for 2%; see
    /// [`crate::error_estimate`]). When set, the sample counts above become the pilot: each
    /// Monte Carlo stage measures its own error, predicts the count that reaches its share of
    /// the target (the target divided by √(number of sampling stages); error falls as
    /// 1/√count), runs again with it, and repeats (at most 3 rounds, counts capped at their
    /// ranges) until its estimate is at or below its share (the counts: samples per texel,
    /// form-factor rays per node, or stochastic Jacobi's rays per node, and VPL particles);
    /// the radiosity solver's tolerance is tightened to a quarter of the target. The texel
    /// grid's own error (the `grid error` stage, [`Self::grid_error_points`]) does not fall
    /// with samples, only with the texel density: it is printed in the estimate beside them
    /// and not counted against the target. Range (0, 1). Default none.
    pub target_error: Option<f32>,
    /// Points at which the bake checks its own texel grid: the direct light's bilinear
    /// reconstruction against the direct light at the point
    /// (`lightmap::grid_error`), added to the error estimate; 0 leaves the check out
    /// (the estimate then covers sampling noise only). Range 0..=1 000 000. Default 16 384.
    pub grid_error_points: u32,
    /// Points at which the finished bake is checked against the in-tree path tracer
    /// (`lightbake::analysis::verify`; the CLI's `--verify N`), spread over the baked
    /// surfaces a viewer can see; 0 leaves the check out. Range 0..=100 000. Default 0.
    pub verify_points: u32,
    /// Paths per point of that check: its reference's noise falls as 1/√paths. Range
    /// 2..=1 048 576. Default 4096.
    pub verify_paths: u32,
    /// Which files to write.
    pub formats: OutputFormats,
}

impl Default for BakeSettings {
    fn default() -> Self {
        Self::preset(Quality::Medium)
    }
}

impl BakeSettings {
    /// The settings of a quality preset.
    pub fn preset(quality: Quality) -> Self {
        let (texel_budget, samples_per_texel, sky_samples, transport_rays, vpl_particles) =
            match quality {
                // Direct samples per texel from the convergence study (docs/convergence.md):
                // direct light costs little per sample, and at 16 spp it was the larger half
                // of the Cornell box's error at 128 form-factor rays.
                Quality::Preview => (1 << 16, 8, 16, 32, 256),
                Quality::Medium => (1 << 18, 32, 64, 128, 1024),
                Quality::High => (1 << 20, 64, 128, 256, 4096),
            };
        let (cluster_texels, cluster_rays, cluster_tolerance) = match quality {
            Quality::Preview => (16, 64, 0.02),
            Quality::Medium => (8, 128, 0.01),
            Quality::High => (8, 128, 0.005),
        };
        Self {
            method: Method::Radiosity,
            solver: SolverChoice::Auto,
            basis: Basis::Linear,
            transport_rays,
            adaptive_gather: true,
            cluster_texels,
            cluster_rays,
            cluster_tolerance,
            transport_budget_mib: 4096,
            solver_tolerance: 1e-3,
            max_solver_iterations: 20_000,
            stochastic_rays_per_node: 64,
            vpl_particles,
            vpl_time_budget_s: None,
            vpl_sequence: Sequence::ScrambledHalton,
            vpl_clamp_distance: None,
            vpl_bias_compensation: false,
            vpl_compensation_rays: 64,
            vpl_max_depth: 16,
            texel_density: None,
            texel_density_from_scene: true,
            texel_budget,
            adaptive_density: true,
            padding: 2,
            max_page_size: 2048,
            samples_per_texel,
            sky_samples,
            max_closed_form_emitters: 256,
            reunwrap: false,
            contact_fit: true,
            denoise: quality != Quality::Preview,
            denoise_radius: 3,
            stitch_seams: true,
            irradiance_volume: false,
            probe_spacing: None,
            probe_rays: match quality {
                Quality::Preview => 256,
                Quality::Medium => 512,
                Quality::High => 1024,
            },
            seed: 0,
            threads: 0,
            memory_budget_mib: 8192,
            max_rays: 100_000_000_000,
            target_error: None,
            grid_error_points: 16_384,
            verify_points: 0,
            verify_paths: 4096,
            formats: OutputFormats::default(),
        }
    }

    /// Fast look (`--quality preview`).
    pub fn preview() -> Self {
        Self::preset(Quality::Preview)
    }

    /// Default (`--quality medium`).
    pub fn medium() -> Self {
        Self::preset(Quality::Medium)
    }

    /// Final bakes (`--quality high`).
    pub fn high() -> Self {
        Self::preset(Quality::High)
    }

    /// Checks every field against its documented range.
    ///
    /// # Errors
    /// [`BakeError::BadSetting`] naming the first field out of range.
    pub fn validate(&self) -> Result<()> {
        for (name, rule) in self.rules() {
            if let Some((value, message)) = rule.broken() {
                return Err(BakeError::BadSetting {
                    name,
                    value,
                    message,
                });
            }
        }
        Ok(())
    }

    /// Every setting with a limit, and its rule: the table [`Self::validate`] checks.
    fn rules(&self) -> Vec<(&'static str, Rule)> {
        use Rule::{Count, Fraction, Holds, Positive};
        let count = |value: u32, min: u64, max: u64, unit| Count {
            value: value as u64,
            min,
            max,
            unit,
        };
        vec![
            (
                "texel_density",
                Holds {
                    ok: self
                        .texel_density
                        .is_none_or(|d| d.is_finite() && d > 0.0 && d <= 1e9),
                    value: format!("{:?}", self.texel_density),
                    message: "must be in (0, 10⁹] texels per metre (per scene unit)",
                },
            ),
            (
                "texel_budget",
                Count {
                    value: self.texel_budget,
                    min: 1_000,
                    max: 100_000_000,
                    unit: " texels",
                },
            ),
            (
                "denoise_radius",
                count(self.denoise_radius, 1, 8, " texels"),
            ),
            ("padding", count(self.padding, 1, 16, " texels")),
            (
                "max_page_size",
                count(self.max_page_size, 64, 16384, " texels"),
            ),
            (
                "samples_per_texel",
                count(self.samples_per_texel, 1, 4096, ""),
            ),
            ("sky_samples", count(self.sky_samples, 1, 65_536, "")),
            ("transport_rays", count(self.transport_rays, 1, 65_536, "")),
            (
                "cluster_texels",
                Holds {
                    ok: self.cluster_texels.is_power_of_two() && self.cluster_texels <= 256,
                    value: self.cluster_texels.to_string(),
                    message: "must be a power of two from 1 to 256 texels",
                },
            ),
            ("cluster_rays", count(self.cluster_rays, 1, 65_536, "")),
            ("cluster_tolerance", Fraction(Some(self.cluster_tolerance))),
            ("solver_tolerance", Fraction(Some(self.solver_tolerance))),
            (
                "max_solver_iterations",
                count(self.max_solver_iterations, 1, u32::MAX as u64, ""),
            ),
            (
                "stochastic_rays_per_node",
                count(self.stochastic_rays_per_node, 1, u32::MAX as u64, ""),
            ),
            (
                "vpl_particles",
                count(self.vpl_particles, 1, 10_000_000, ""),
            ),
            (
                "vpl_time_budget_s",
                Positive(self.vpl_time_budget_s, "a positive number of seconds"),
            ),
            ("target_error", Fraction(self.target_error.map(f64::from))),
            (
                "vpl_clamp_distance",
                Positive(
                    self.vpl_clamp_distance.map(f64::from),
                    "a positive distance in metres",
                ),
            ),
            (
                "vpl_max_depth",
                count(self.vpl_max_depth, 0, MAX_VPL_DEPTH as u64, ""),
            ),
            (
                "probe_spacing",
                Positive(
                    self.probe_spacing.map(f64::from),
                    "a positive distance in metres",
                ),
            ),
            ("probe_rays", count(self.probe_rays, 1, 65_536, "")),
            (
                "max_rays",
                Count {
                    value: self.max_rays,
                    min: 1_000_000,
                    max: 1_000_000_000_000_000,
                    unit: " rays",
                },
            ),
            (
                "grid_error_points",
                count(self.grid_error_points, 0, 1_000_000, " points"),
            ),
            (
                "verify_points",
                count(self.verify_points, 0, 100_000, " points"),
            ),
            (
                "verify_paths",
                count(self.verify_paths, 2, 1_048_576, " paths per point"),
            ),
            (
                "memory_budget_mib",
                Count {
                    value: self.memory_budget_mib,
                    min: 1,
                    max: u64::MAX,
                    unit: " MiB",
                },
            ),
            (
                "formats",
                Holds {
                    ok: self.formats.exr || self.formats.hdr || self.formats.ktx2,
                    value: "none".into(),
                    message: "at least one HDR format (exr, hdr, ktx2) must be written",
                },
            ),
        ]
    }
}

/// One setting's rule in [`BakeSettings::validate`]'s table.
enum Rule {
    /// A count in `min..=max` (`unit` after the numbers, with its leading space).
    Count {
        value: u64,
        min: u64,
        max: u64,
        unit: &'static str,
    },
    /// A relative amount in (0, 1), when set.
    Fraction(Option<f64>),
    /// A finite positive number, when set (`what` it is, in words).
    Positive(Option<f64>, &'static str),
    /// A condition of its own: whether it holds, the value shown and the message.
    Holds {
        ok: bool,
        value: String,
        message: &'static str,
    },
}

impl Rule {
    /// The value and the message when the rule is broken.
    fn broken(self) -> Option<(String, String)> {
        match self {
            Rule::Count {
                value,
                min,
                max,
                unit,
            } => (!(min..=max).contains(&value)).then(|| {
                let range = if max == u64::MAX || max == u32::MAX as u64 {
                    format!("at least {min}{unit}")
                } else {
                    format!("{min}..={max}{unit}")
                };
                (value.to_string(), format!("must be {range}"))
            }),
            Rule::Fraction(value) => value
                .filter(|v| !(v.is_finite() && *v > 0.0 && *v < 1.0))
                .map(|v| {
                    let message = "must be a relative amount in (0, 1) (0.02 = 2%)";
                    (v.to_string(), message.to_string())
                }),
            Rule::Positive(value, what) => value
                .filter(|v| !(v.is_finite() && *v > 0.0))
                .map(|v| (v.to_string(), format!("must be {what}"))),
            Rule::Holds { ok, value, message } => (!ok).then(|| (value, message.to_string())),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn presets_are_valid_and_ordered() {
        let (p, m, h) = (
            BakeSettings::preview(),
            BakeSettings::medium(),
            BakeSettings::high(),
        );
        for s in [&p, &m, &h] {
            s.validate().unwrap();
        }
        assert!(p.texel_budget < m.texel_budget && m.texel_budget < h.texel_budget);
        assert!(p.samples_per_texel < m.samples_per_texel);
        assert_eq!(BakeSettings::default(), m);
    }

    /// Every row of the table: the setting just outside its limit is refused by its name,
    /// and just inside it is accepted.
    #[test]
    fn every_limit_is_checked_at_its_edge() {
        type Edit = fn(&mut BakeSettings, bool);
        let edges: [(&str, Edit); 12] = [
            ("texel_budget", |s, out| {
                s.texel_budget = if out { 999 } else { 1_000 }
            }),
            ("denoise_radius", |s, out| {
                s.denoise_radius = if out { 9 } else { 8 }
            }),
            ("padding", |s, out| s.padding = if out { 17 } else { 16 }),
            ("max_page_size", |s, out| {
                s.max_page_size = if out { 63 } else { 64 }
            }),
            ("cluster_texels", |s, out| {
                s.cluster_texels = if out { 512 } else { 256 }
            }),
            ("cluster_tolerance", |s, out| {
                s.cluster_tolerance = if out { 1.0 } else { 0.99 }
            }),
            ("target_error", |s, out| {
                s.target_error = Some(if out { 0.0 } else { 0.5 })
            }),
            ("vpl_clamp_distance", |s, out| {
                s.vpl_clamp_distance = Some(if out { f32::INFINITY } else { 1.0 })
            }),
            ("vpl_max_depth", |s, out| {
                s.vpl_max_depth = if out {
                    MAX_VPL_DEPTH + 1
                } else {
                    MAX_VPL_DEPTH
                }
            }),
            ("max_rays", |s, out| {
                s.max_rays = if out { 999_999 } else { 1_000_000 }
            }),
            ("memory_budget_mib", |s, out| {
                s.memory_budget_mib = if out { 0 } else { 1 }
            }),
            ("verify_paths", |s, out| {
                s.verify_paths = if out { 1 } else { 2 }
            }),
        ];
        for (name, edit) in edges {
            let mut s = BakeSettings::default();
            edit(&mut s, false);
            assert!(s.validate().is_ok(), "{name} at its limit");
            edit(&mut s, true);
            match s.validate() {
                Err(BakeError::BadSetting { name: n, .. }) => assert_eq!(n, name),
                other => panic!("{name} past its limit: {other:?}"),
            }
        }
        assert_eq!(BakeSettings::default().rules().len(), 27);
    }

    #[test]
    fn out_of_range_fields_are_named() {
        let s = BakeSettings {
            texel_density: Some(f32::NAN),
            ..BakeSettings::default()
        };
        let msg = s.validate().unwrap_err().to_string();
        assert!(msg.contains("texel_density"), "{msg}");
        let s = BakeSettings {
            padding: 0,
            ..BakeSettings::default()
        };
        assert!(s.validate().unwrap_err().to_string().contains("padding"));
    }
}
