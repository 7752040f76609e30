//! Bake settings: [`BakeSettings`], a group of plain fields per stage that reads them (each
//! group's module has its table of units, ranges and preset values), the named quality
//! presets the CLI's `--quality` and the Bevy plugin map onto, and one table-driven
//! [`BakeSettings::validate`].
//!
//! | group | module | the stage that reads it |
//! |---|---|---|
//! | `layout` | [`layout`] | unwrap, texel density, atlas packing |
//! | `direct` | [`direct`] | direct light |
//! | `radiosity` | [`radiosity`] | radiosity: solver, form factors, hierarchical coarse level |
//! | `vpl` | [`vpl`] | instant radiosity |
//! | `finish` | [`finish`] | contact fit, denoise, seam stitch |
//! | `volume` | [`volume`] | irradiance volume |
//! | `checks` | [`checks`] | grid error, `--verify` |
//! | `groups` | [`groups`] | the lighting passes, once per light group |
//!
//! The method, the seed, the thread count, the memory and ray limits, the target error and
//! the output formats steer the whole bake and sit on [`BakeSettings`] itself.

use serde::{Deserialize, Serialize};

use crate::error::{BakeError, Result};
pub use crate::sampling::Sequence;

pub mod checks;
pub mod direct;
pub mod finish;
pub mod groups;
pub mod layout;
pub mod radiosity;
pub mod volume;
pub mod vpl;

pub use checks::CheckSettings;
pub use direct::DirectSettings;
pub use finish::FinishSettings;
pub use groups::LightGroup;
pub use layout::LayoutSettings;
pub use radiosity::RadiositySettings;
pub use volume::VolumeSettings;
pub use vpl::VplSettings;

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
    /// KTX2, BC6H unsigned half float blocks (`lightmap_N.bc6h.ktx2`, 1 byte per texel; Bevy
    /// loads it as `Bc6hRgbUfloat` on a GPU with BC compression). Every chart then gets 4×4
    /// blocks of its own and every instance starts on a block.
    Ktx2Bc6h,
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
    /// KTX2, BC6H blocks (`lightmap_N.bc6h.ktx2`); the layout then gives every chart 4×4
    /// blocks of its own (a mesh's own `TEXCOORD_1` charts moved onto them by whole texels).
    /// Default off.
    #[serde(default)]
    pub ktx2_bc6h: bool,
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
            ktx2_bc6h: hdr.contains(&ImageFormat::Ktx2Bc6h),
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
            ktx2_bc6h: false,
            png_preview: true,
        }
    }
}

/// How punctual-light parameters the glTF leaves open are read.
///
/// The glTF specification says `KHR_lights_punctual` colours are linear and a light without
/// `range` reaches infinitely far. Bevy 0.20's glTF loader reads the colour as sRGB and gives
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
    /// Match what Bevy 0.20's glTF loader does, so a baked light equals Bevy's real-time one:
    /// sRGB light colours, no range = 20 m.
    #[cfg_attr(feature = "clap", value(name = "bevy"))]
    BevyGltfLoader,
}

/// Everything that steers a bake: the method, a group of settings per stage that reads them
/// (each group's module has its table of units, ranges and preset values), and the limits of
/// the whole bake. Build it from a preset and change fields:
///
/// ```
/// use lightbake::settings::{BakeSettings, Quality};
/// let mut s = BakeSettings::preset(Quality::High);
/// s.layout.texel_density = Some(64.0);
/// s.direct.samples_per_texel = 128;
/// assert!(s.validate().is_ok());
/// ```
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct BakeSettings {
    /// How light is computed. Default [`Method::Radiosity`].
    pub method: Method,
    /// The unwrap, the texel density and the atlas ([`layout`]).
    pub layout: LayoutSettings,
    /// The direct pass's samples ([`direct`]).
    pub direct: DirectSettings,
    /// The radiosity pass: solver, basis, form-factor rays, coarse level ([`radiosity`]).
    pub radiosity: RadiositySettings,
    /// Instant radiosity's particles and gather ([`vpl`]).
    pub vpl: VplSettings,
    /// The finishing passes: contact fit, denoiser, seam stitch ([`finish`]).
    pub finish: FinishSettings,
    /// The irradiance volume for dynamic objects ([`volume`]).
    pub volume: VolumeSettings,
    /// The bake's checks of itself: the texel grid's error, `--verify` ([`checks`]).
    pub checks: CheckSettings,
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
    /// [`crate::error_estimate`]). When set, the sample counts become the pilot: each
    /// Monte Carlo stage measures its own error, predicts the count that reaches its share of
    /// the target (the target divided by √(number of sampling stages); error falls as
    /// 1/√count), runs again with it, and repeats (at most 3 rounds, counts capped at their
    /// ranges) until its estimate is at or below its share (the counts: samples per texel,
    /// form-factor rays per node, or stochastic Jacobi's rays per node, and VPL particles);
    /// the radiosity solver's tolerance is tightened to a quarter of the target. The texel
    /// grid's own error (the `grid error` stage, [`CheckSettings::grid_error_points`]) does
    /// not fall with samples, only with the texel density: it is printed in the estimate
    /// beside them and not counted against the target. Range (0, 1). Default none.
    pub target_error: Option<f32>,
    /// Which files to write.
    pub formats: OutputFormats,
    /// Light groups, each baked into lightmaps of its own ([`groups`]); the bake's own pages
    /// are their sum. Default none.
    pub groups: Vec<LightGroup>,
}

impl Default for BakeSettings {
    fn default() -> Self {
        Self::preset(Quality::Medium)
    }
}

impl BakeSettings {
    /// The settings of a quality preset: each group's preset.
    pub fn preset(quality: Quality) -> Self {
        Self {
            method: Method::Radiosity,
            layout: LayoutSettings::preset(quality),
            direct: DirectSettings::preset(quality),
            radiosity: RadiositySettings::preset(quality),
            vpl: VplSettings::preset(quality),
            finish: FinishSettings::preset(quality),
            volume: VolumeSettings::preset(quality),
            checks: CheckSettings::default(),
            seed: 0,
            threads: 0,
            memory_budget_mib: 8192,
            max_rays: 100_000_000_000,
            target_error: None,
            formats: OutputFormats::default(),
            groups: Vec::new(),
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
    /// [`BakeError::BadSetting`] naming the first field out of range (as its path, e.g.
    /// `direct.samples_per_texel`).
    pub fn validate(&self) -> Result<()> {
        groups::check(&self.groups)?;
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

    /// Every setting with a limit, and its rule: the table [`Self::validate`] checks, each
    /// group's rows and then the whole bake's.
    fn rules(&self) -> Vec<(&'static str, Rule)> {
        let mut rules = self.layout.rules();
        rules.extend(self.direct.rules());
        rules.extend(self.radiosity.rules());
        rules.extend(self.vpl.rules());
        rules.extend(self.finish.rules());
        rules.extend(self.volume.rules());
        rules.extend(self.checks.rules());
        rules.extend([
            (
                "target_error",
                Rule::Fraction(self.target_error.map(f64::from)),
            ),
            (
                "max_rays",
                Rule::count(self.max_rays, 1_000_000, 1_000_000_000_000_000, " rays"),
            ),
            (
                "memory_budget_mib",
                Rule::count(self.memory_budget_mib, 1, u64::MAX, " MiB"),
            ),
            (
                "formats",
                Rule::Holds {
                    ok: self.formats.exr || self.formats.hdr || self.formats.ktx2,
                    value: "none".into(),
                    message: "at least one HDR format (exr, hdr, ktx2) must be written",
                },
            ),
        ]);
        rules
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
    /// A count `value` in `min..=max` (`unit` after the numbers, with its leading space).
    fn count(value: impl Into<u64>, min: u64, max: u64, unit: &'static str) -> Self {
        Rule::Count {
            value: value.into(),
            min,
            max,
            unit,
        }
    }

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
        assert!(p.layout.texel_budget < m.layout.texel_budget);
        assert!(m.layout.texel_budget < h.layout.texel_budget);
        assert!(p.direct.samples_per_texel < m.direct.samples_per_texel);
        assert_eq!(BakeSettings::default(), m);
    }

    /// Every row of the table: the setting just outside its limit is refused by its name,
    /// and just inside it is accepted.
    #[test]
    fn every_limit_is_checked_at_its_edge() {
        type Edit = fn(&mut BakeSettings, bool);
        let edges: [(&str, Edit); 18] = [
            ("layout.texel_budget", |s, out| {
                s.layout.texel_budget = if out { 999 } else { 1_000 }
            }),
            ("finish.denoise_radius", |s, out| {
                s.finish.denoise_radius = if out { 9 } else { 8 }
            }),
            ("layout.padding", |s, out| {
                s.layout.padding = if out { 17 } else { 16 }
            }),
            ("layout.max_page_size", |s, out| {
                s.layout.max_page_size = if out { 63 } else { 64 }
            }),
            ("radiosity.cluster_texels", |s, out| {
                s.radiosity.cluster_texels = if out { 512 } else { 256 }
            }),
            ("radiosity.cache_spacing", |s, out| {
                s.radiosity.cache_spacing = if out { 128 } else { 64 }
            }),
            ("radiosity.cache_accuracy", |s, out| {
                s.radiosity.cache_accuracy = if out { 4.5 } else { 4.0 }
            }),
            ("radiosity.cluster_tolerance", |s, out| {
                s.radiosity.cluster_tolerance = if out { 1.0 } else { 0.99 }
            }),
            ("target_error", |s, out| {
                s.target_error = Some(if out { 0.0 } else { 0.5 })
            }),
            ("vpl.clamp_distance", |s, out| {
                s.vpl.clamp_distance = Some(if out { f32::INFINITY } else { 1.0 })
            }),
            ("vpl.cut_size", |s, out| {
                s.vpl.cut_size = if out { 65_537 } else { 65_536 }
            }),
            ("vpl.max_depth", |s, out| {
                s.vpl.max_depth = if out {
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
            ("checks.verify_paths", |s, out| {
                s.checks.verify_paths = if out { 1 } else { 2 }
            }),
            ("volume.regions", |s, out| {
                s.volume.regions = if out { 65 } else { 64 }
            }),
            ("volume.probes_per_headroom", |s, out| {
                s.volume.probes_per_headroom = if out { 65 } else { 64 }
            }),
            ("volume.probes_per_headroom", |s, out| {
                s.volume.probes_per_headroom = if out { 0 } else { 1 }
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
        assert_eq!(BakeSettings::default().rules().len(), 32);
    }

    #[test]
    fn out_of_range_fields_are_named() {
        let mut s = BakeSettings::default();
        s.layout.texel_density = Some(f32::NAN);
        let msg = s.validate().unwrap_err().to_string();
        assert!(msg.contains("layout.texel_density"), "{msg}");
        let mut s = BakeSettings::default();
        s.layout.padding = 0;
        assert!(s.validate().unwrap_err().to_string().contains("padding"));
    }
}
