//! Interreflected light by radiosity over the texel nodes (Cohen & Wallace 1993; Dutré et
//! al., *Advanced Global Illumination*, ch. 6).
//!
//! lightbake splits the light at every node into the direct irradiance H_d (from the direct
//! pass, which treats lights, the sun, the sky and emitters exactly) and the irradiance from
//! reflected light H_r = F·B, where B is the exitance of reflected light:
//!
//! B = ρ∘(H_d + F·B)  ⇔  (I − diag(ρ)·F)·B = S,  S = ρ∘H_d,
//!
//! and the lightmap stores (H_d + F·B)/π. In a closed room of uniform emission E = π·L_e and
//! albedo ρ this gives H = E/(1 − ρ), the classic B = E/(1 − ρ) with the emission counted in
//! H_d. Emitters are not counted twice: their emission is direct light, and B carries only
//! reflection.

//!
//! | module | what it holds |
//! |---|---|
//! | [`nodes`] | the unknowns: one node per valid texel, its albedo and basis area |
//! | [`basis`] | ∫φᵢ dA of every node's basis function |
//! | [`hit_mapper`] | a ray hit → the nodes and basis weights there |
//! | [`support`] | transport-ray start points on a node's basis support |
//! | [`exitance_grid`] | a field B per node on the lightmap pages, for gathers |
//! | [`monte_carlo`] | form factors by Monte Carlo (Galerkin rows of F) |
//! | [`hemicube`] | form factors by Cohen & Greenberg's hemicube, for comparison |
//! | [`stochastic_jacobi`] | the matrix-free solver (it traces rays, so it lives here) |
//! | [`clusters`] | texel clusters: cuts through a quadtree per chart |
//! | [`coarse`] | the clusters' form factors and the refinement oracle |
//! | [`hierarchical`] | the coarse solve, its refinement and the per-texel final gather |
//! | [`hierarchical_solve`] | one round of the hierarchical solve as stages: coarse level, final gather, correction, reflection, error |
//! | [`group_solve`] | the same round for several light groups at once, their gathers' rays shared |
//! | [`ray_allocation`] | the final gather's rays per node, by each node's noise in a pilot |
//! | [`gather_cache`] | the final gather at sparse records, interpolated between them (irradiance caching) |
//! | [`error_estimate`] | the pass's estimate of its own error |
//!
//! The linear algebra (the matrix F and the matrix solvers) is [`crate::solve`].

pub mod basis;
pub mod clusters;
pub mod coarse;
pub mod coarse_kept;
pub mod error_estimate;
pub mod exitance_grid;
pub mod gather_cache;
pub mod group_solve;
pub mod hemicube;
pub mod hierarchical;
pub mod hierarchical_solve;
pub mod hit_mapper;
pub mod monte_carlo;
pub mod nodes;
pub mod ray_allocation;
pub mod stochastic_jacobi;
pub mod support;

use glam::Vec3;
use serde::Serialize;

use crate::context::BakeContext;
use crate::error::{BakeError, Result};
use crate::progress::Progress;
use crate::settings::{Basis, SolverChoice};
use crate::solve::transport::Transport;
use crate::solve::{self, AUTO_MATRIX_NODES, DIRECT_MAX_NODES, Solution, SolveOptions, System};
pub use error_estimate::{gather_error, hierarchical_error};
use hierarchical::{CoarseReport, HierarchyOptions};
pub use hit_mapper::HitMapper;
pub use nodes::Nodes;
use stochastic_jacobi::StochasticOptions;

/// Which solver runs, and why.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct SolverPlan {
    /// The solver (never `Auto`).
    pub choice: SolverChoice,
    /// Why.
    pub reason: String,
    /// Estimated bytes of the transport matrix (0 when not estimated).
    pub transport_estimate_bytes: u64,
    /// Bytes the solver allocates beside the matrix, with the nodes and the hit mapper
    /// ([`SolverChoice::working_bytes`], `hierarchical::planned_bytes`).
    pub solver_working_bytes: u64,
}

/// Counters of the radiosity pass, for the report.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct RadiosityReport {
    /// Solver name.
    pub solver: &'static str,
    /// Why it was chosen.
    pub solver_reason: String,
    /// Basis.
    pub basis: Basis,
    /// Unknowns (valid texels).
    pub nodes: usize,
    /// Largest albedo component.
    pub max_albedo: f32,
    /// Transport matrix: stored entries (0 when matrix-free).
    pub transport_nnz: usize,
    /// Transport matrix: bytes (0 when matrix-free).
    pub transport_bytes: u64,
    /// Transport matrix: estimate made before building it.
    pub transport_estimate_bytes: u64,
    /// Bytes planned for the solver beside the matrix (with the nodes and the hit mapper).
    pub solver_working_bytes: u64,
    /// The solver's result (history, iterations, stop reason; for the hierarchical solve,
    /// the last coarse solve's), without its per-node vectors.
    pub solution: Solution,
    /// The hierarchical solve's coarse level (none for the other solvers).
    pub coarse: Option<CoarseReport>,
    /// The hierarchical solve's estimated bias from its coarse level, relative RMS (part of
    /// the error estimate; none for the other solvers).
    pub coarse_bias: Option<f64>,
}

/// The hierarchical solve's options for these nodes and settings: the coarse matrix capped
/// at [`solve::COARSE_BYTES_PER_NODE`] per node and by `budget` bytes.
pub fn hierarchy_options(ctx: &BakeContext<'_>, nodes: &Nodes, budget: u64) -> HierarchyOptions {
    let s = ctx.settings;
    HierarchyOptions {
        top_level: s.radiosity.cluster_texels.trailing_zeros() as u8,
        cell_rays: s.radiosity.cluster_rays,
        tolerance: s.radiosity.cluster_tolerance,
        max_matrix_bytes: (nodes.len() as u64 * solve::COARSE_BYTES_PER_NODE).min(budget),
        solver_tolerance: s.radiosity.solver_tolerance,
        max_iterations: s.radiosity.max_solver_iterations,
    }
}

/// Decides the solver for these nodes (resolving `Auto`) and checks the matrix budget.
///
/// # Errors
/// [`BakeError::OverMemoryBudget`] when a matrix solver was asked for and the matrix does not
/// fit; [`BakeError::BadSetting`] when `direct` is asked for too many nodes.
pub fn plan_solver(ctx: &BakeContext<'_>, nodes: &Nodes) -> Result<SolverPlan> {
    let s = ctx.settings;
    const MIB: u64 = 1024 * 1024;
    let (budget, memory_room, rest) = solver_budget(ctx);
    let limit = if memory_room < s.radiosity.transport_budget_mib * MIB {
        format!(
            "the memory budget ({} MiB) leaves {:.0} MiB beside the rest of the bake ({:.0} MiB); raise --memory-budget",
            s.memory_budget_mib,
            memory_room as f64 / MIB as f64,
            rest as f64 / MIB as f64
        )
    } else {
        "raise the transport budget".to_string()
    };
    let estimate = if s.radiosity.solver.needs_matrix() || s.radiosity.solver == SolverChoice::Auto
    {
        monte_carlo::estimate_bytes(ctx, nodes, s.radiosity.transport_rays, s.radiosity.basis)
    } else {
        0
    };
    // The budget holds the matrix and the solver's own vectors and matrix copies, beside the
    // nodes and the hit mapper every solver has.
    let n = nodes.len();
    let common = common_bytes(ctx, n);
    let fits_with = |c: SolverChoice| common + estimate + c.working_bytes(n, estimate) <= budget;
    let (choice, reason) = match s.radiosity.solver {
        SolverChoice::Auto if n > AUTO_MATRIX_NODES => (
            SolverChoice::Hierarchical,
            format!(
                "{n} nodes, above {AUTO_MATRIX_NODES}: the full matrix would take {:.0} MiB ({:.0} bytes per node); the hierarchical solve's memory is linear in the nodes",
                estimate as f64 / MIB as f64,
                estimate as f64 / n as f64
            ),
        ),
        SolverChoice::Auto => solve::choose(n, nodes.max_albedo(), fits_with),
        c => (c, "chosen in the settings".to_string()),
    };
    let estimate = if choice.needs_matrix() { estimate } else { 0 };
    let working = common
        + match choice {
            SolverChoice::Hierarchical => {
                hierarchical::planned_bytes(n, ctx.layout.page_texels(), ctx.rays.triangles.len())
            }
            c => c.working_bytes(n, estimate),
        };
    if choice == SolverChoice::Hierarchical && working > budget {
        return Err(BakeError::OverMemoryBudget {
            needed_mib: working as f64 / MIB as f64,
            budget_mib: budget as f64 / MIB as f64,
            breakdown: format!(
                "the hierarchical solve of {n} nodes needs {:.0} MiB for its vectors and coarse matrix; lower the texel density, or {limit}",
                working as f64 / MIB as f64
            ),
        });
    }
    if choice.needs_matrix() && !fits_with(choice) {
        return Err(BakeError::OverMemoryBudget {
            needed_mib: (estimate + working) as f64 / MIB as f64,
            budget_mib: budget as f64 / MIB as f64,
            breakdown: format!(
                "the {} solver needs the transport matrix of {} nodes × {} rays ({:.0} MiB) and {:.0} MiB beside it; use --solver hierarchical (no full matrix), or {limit}",
                choice.name(),
                nodes.len(),
                s.radiosity.transport_rays,
                estimate as f64 / MIB as f64,
                working as f64 / MIB as f64
            ),
        });
    }
    if choice == SolverChoice::Direct && nodes.len() > DIRECT_MAX_NODES {
        return Err(BakeError::BadSetting {
            name: "radiosity.solver",
            value: "direct".into(),
            message: format!(
                "the dense LU solve is limited to {DIRECT_MAX_NODES} nodes and this bake has {}; use auto or krylov",
                nodes.len()
            ),
        });
    }
    Ok(SolverPlan {
        choice,
        reason,
        transport_estimate_bytes: estimate,
        solver_working_bytes: working,
    })
}

/// Bytes every radiosity solve holds beside its solver's: the nodes (their patch, area,
/// albedo and two flags: 22 bytes each) and the hit mapper (a node and owner per page texel,
/// UVs and owner per triangle).
fn common_bytes(ctx: &BakeContext<'_>, nodes: usize) -> u64 {
    nodes as u64 * (4 + 4 + 12 + 1 + 1)
        + ctx.layout.page_texels() * 12
        + ctx.rays.triangles.len() as u64 * 32
}

/// The bytes the solvers may take: the smaller of the transport budget and what the memory
/// budget leaves beside the rest of the bake (patches, pages, ray tracing; see
/// `crate::memory`); also that room and the rest.
fn solver_budget(ctx: &BakeContext<'_>) -> (u64, u64, u64) {
    const MIB: u64 = 1024 * 1024;
    let s = ctx.settings;
    let rest = crate::memory::estimate_from_layout(ctx.scene, ctx.layout).total;
    let memory_room = (s.memory_budget_mib * MIB).saturating_sub(rest);
    let budget = (s.radiosity.transport_budget_mib * MIB).min(memory_room);
    (budget, memory_room, rest)
}

/// The bytes the hierarchical solve of `groups` light groups at once holds at its peak
/// ([`group_solve`]: each group's fields, grids and coarse level held together, the
/// gathers' per-field samples, and each group's copy of the scene), and the solvers' budget
/// ([`plan_solver`]'s).
pub fn groups_bytes(ctx: &BakeContext<'_>, nodes: &Nodes, groups: usize) -> (u64, u64) {
    let n = nodes.len();
    let one = hierarchical::planned_bytes(n, ctx.layout.page_texels(), ctx.rays.triangles.len());
    let k = groups as u64;
    let needed =
        common_bytes(ctx, n) + k * one + (k + 1) * 48 * n as u64 + k * scene_bytes(ctx.scene);
    (needed, solver_budget(ctx).0)
}

/// Bytes of a scene's meshes and textures (what a copy of it holds).
fn scene_bytes(scene: &crate::scene::Scene) -> u64 {
    let meshes: usize = (scene.meshes.iter())
        .map(|m| {
            let uvs = m.uv0.as_ref().map_or(0, Vec::len) + m.uv1.as_ref().map_or(0, Vec::len);
            (m.positions.len() + m.normals.len()) * 12 + uvs * 8 + m.indices.len() * 4
        })
        .sum();
    let textures: usize = scene.textures.iter().map(|t| t.rgba8.len() * 4).sum();
    (meshes + textures) as u64
}

/// S = ρ∘H_d per node, from per-patch direct irradiance.
pub fn source(nodes: &Nodes, direct: &[Vec3]) -> Vec<Vec3> {
    nodes
        .patch
        .iter()
        .zip(&nodes.albedo)
        .map(|(&p, rho)| *rho * direct[p as usize])
        .collect()
}

/// Builds the transport matrix (Monte Carlo, `settings.radiosity.transport_rays` per node).
pub fn build_transport(ctx: &BakeContext<'_>, nodes: &Nodes, progress: &Progress) -> Transport {
    monte_carlo::build(
        ctx,
        nodes,
        ctx.settings.radiosity.transport_rays,
        ctx.settings.radiosity.basis,
        progress,
    )
}

/// Solves for B and returns the solution (with `indirect` = F·B per node).
pub fn solve_system(
    ctx: &BakeContext<'_>,
    nodes: &Nodes,
    plan: &SolverPlan,
    transport: Option<&Transport>,
    source: &[Vec3],
    progress: &Progress,
) -> Solution {
    let s = ctx.settings;
    let residual_tolerance = residual_tolerance(s.radiosity.solver_tolerance, nodes.max_albedo());
    match (plan.choice, transport) {
        (SolverChoice::Hierarchical, _) => {
            panic!("the hierarchical solve runs as its own stages (see bake::passes)")
        }
        (SolverChoice::StochasticJacobi, _) | (_, None) => {
            let mapper = HitMapper::new(*ctx, nodes, s.radiosity.basis);
            let options = StochasticOptions {
                first_iteration_rays: nodes.len() as u64
                    * s.radiosity.stochastic_rays_per_node as u64,
                tolerance: residual_tolerance,
                max_iterations: s.radiosity.max_solver_iterations,
            };
            stochastic_jacobi::solve(ctx, nodes, &mapper, source, &options, progress)
        }
        (choice, Some(transport)) => {
            let system = System {
                progress: Some(progress),
                ..system(transport, nodes, source)
            };
            let options = SolveOptions {
                tolerance: residual_tolerance,
                max_iterations: s.radiosity.max_solver_iterations,
            };
            solve::solve_matrix(choice, &system, &options)
        }
    }
}

/// The linear system of `nodes` (their albedos and areas) with matrix `transport` and source
/// `source`, publishing nowhere.
pub fn system<'a>(transport: &'a Transport, nodes: &'a Nodes, source: &'a [Vec3]) -> System<'a> {
    System {
        transport,
        albedo: &nodes.albedo,
        source,
        area: &nodes.area,
        progress: None,
    }
}

/// The relative residual that guarantees relative error `target`:
/// target·(1 − ρ_max), at least 10⁻¹².
pub fn residual_tolerance(target: f64, max_albedo: f32) -> f64 {
    (target * (1.0 - max_albedo as f64)).max(1e-12)
}

/// Per-patch irradiance from reflected light (zero for invalid patches).
pub fn per_patch(nodes: &Nodes, indirect: &[Vec3], patches: usize) -> Vec<Vec3> {
    let mut out = vec![Vec3::ZERO; patches];
    for (n, &p) in nodes.patch.iter().enumerate() {
        out[p as usize] = indirect[n];
    }
    out
}
