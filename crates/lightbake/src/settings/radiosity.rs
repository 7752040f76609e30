//! The settings of the radiosity pass: the solver, the basis, the form-factor rays and the
//! hierarchical solve's coarse level ([`RadiositySettings`], `BakeSettings::radiosity`).
//!
//! | field | unit | range | preview | medium | high |
//! |---|---|---|---|---|---|
//! | `solver` | – | [`SolverChoice`] | auto | auto | auto |
//! | `basis` | – | [`Basis`] | linear | linear | linear |
//! | `transport_rays` | rays per node | 1..=65 536 | 32 | 128 | 256 |
//! | `adaptive_gather` | – | bool | true | true | true |
//! | `cache_spacing` | texels | 0 or a power of two, 2..=64 | 0 | 0 | 0 |
//! | `cache_accuracy` | – | (0, 4] | 0.5 | 0.5 | 0.5 |
//! | `cluster_texels` | texels | power of two, 1..=256 | 16 | 8 | 8 |
//! | `cluster_rays` | rays per cell | 1..=65 536 | 64 | 128 | 128 |
//! | `cluster_tolerance` | relative | (0, 1) | 0.02 | 0.01 | 0.005 |
//! | `transport_budget_mib` | MiB | any | 4096 | 4096 | 4096 |
//! | `solver_tolerance` | relative | (0, 1) | 10⁻³ | 10⁻³ | 10⁻³ |
//! | `max_solver_iterations` | sweeps | ≥ 1 | 20 000 | 20 000 | 20 000 |
//! | `stochastic_rays_per_node` | rays per node | ≥ 1 | 64 | 64 | 64 |

use serde::{Deserialize, Serialize};

use super::{Basis, Quality, Rule, SolverChoice};

/// How the radiosity pass solves for the interreflected light.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct RadiositySettings {
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
    /// pilot of a quarter of them: the same rays in all, more where the gathered light is
    /// noisy. Off: `transport_rays` at every node (the rays of the full matrix's rows).
    /// Needs `transport_rays` ≥ 16. Default on.
    pub adaptive_gather: bool,
    /// The hierarchical solve's final gather through an irradiance cache (Ward, Rubinstein &
    /// Clear 1988; module `radiosity::gather_cache`): gathered at the corners of cells of
    /// this many texels, and at the corners of their quarters where the light or the
    /// geometry changes within them, and interpolated between (`transport_rays` rays at each
    /// record; `adaptive_gather` does not apply). 0: gathered at every node. A power of two,
    /// 2..=64, or 0. Default 0.
    pub cache_spacing: u32,
    /// The irradiance cache's accuracy, Ward's a: a cell is interpolated when its diagonal
    /// over the harmonic mean distance of each corner's rays, plus √(1 − n·n') of the
    /// corners' normals, is at most this (smaller: more records). Range (0, 4]. Default 0.5.
    pub cache_accuracy: f32,
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
    /// ([`SolverChoice::working_bytes`]), MiB; beyond it `Auto` takes the hierarchical solve
    /// (which must fit it too) and the matrix solvers refuse. The smaller of this and
    /// what `BakeSettings::memory_budget_mib` leaves beside the rest of the bake applies.
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
}

impl Default for RadiositySettings {
    fn default() -> Self {
        Self::preset(Quality::Medium)
    }
}

impl RadiositySettings {
    /// The radiosity pass of a quality preset.
    pub fn preset(quality: Quality) -> Self {
        let (transport_rays, cluster_texels, cluster_rays, cluster_tolerance) = match quality {
            Quality::Preview => (32, 16, 64, 0.02),
            Quality::Medium => (128, 8, 128, 0.01),
            Quality::High => (256, 8, 128, 0.005),
        };
        Self {
            solver: SolverChoice::Auto,
            basis: Basis::Linear,
            transport_rays,
            adaptive_gather: true,
            cache_spacing: 0,
            cache_accuracy: 0.5,
            cluster_texels,
            cluster_rays,
            cluster_tolerance,
            transport_budget_mib: 4096,
            solver_tolerance: 1e-3,
            max_solver_iterations: 20_000,
            stochastic_rays_per_node: 64,
        }
    }

    /// The group's rows of the validation table.
    pub(super) fn rules(&self) -> Vec<(&'static str, Rule)> {
        let at_least_one = |value: u32| Rule::count(value, 1, u32::MAX as u64, "");
        vec![
            (
                "radiosity.transport_rays",
                Rule::count(self.transport_rays, 1, 65_536, ""),
            ),
            (
                "radiosity.cache_spacing",
                Rule::Holds {
                    ok: self.cache_spacing == 0
                        || (self.cache_spacing.is_power_of_two()
                            && (2..=64).contains(&self.cache_spacing)),
                    value: self.cache_spacing.to_string(),
                    message: "must be 0 (no cache) or a power of two from 2 to 64 texels",
                },
            ),
            (
                "radiosity.cache_accuracy",
                Rule::Holds {
                    ok: self.cache_accuracy > 0.0 && self.cache_accuracy <= 4.0,
                    value: self.cache_accuracy.to_string(),
                    message: "must be above 0 and at most 4",
                },
            ),
            (
                "radiosity.cluster_texels",
                Rule::Holds {
                    ok: self.cluster_texels.is_power_of_two() && self.cluster_texels <= 256,
                    value: self.cluster_texels.to_string(),
                    message: "must be a power of two from 1 to 256 texels",
                },
            ),
            (
                "radiosity.cluster_rays",
                Rule::count(self.cluster_rays, 1, 65_536, ""),
            ),
            (
                "radiosity.cluster_tolerance",
                Rule::Fraction(Some(self.cluster_tolerance)),
            ),
            (
                "radiosity.solver_tolerance",
                Rule::Fraction(Some(self.solver_tolerance)),
            ),
            (
                "radiosity.max_solver_iterations",
                at_least_one(self.max_solver_iterations),
            ),
            (
                "radiosity.stochastic_rays_per_node",
                at_least_one(self.stochastic_rays_per_node),
            ),
        ]
    }
}
