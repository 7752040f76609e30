//! Analysis: the brute-force path tracer that error measurements compare against
//! (`reference`), bakes of any layout scored against it at surface points (`points`) and
//! densely next to contacts and seams (`edges`), the convergence study of error against run
//! time ([`study`]), a finished bake checked against the path tracer (`bake --verify`,
//! [`verify`](mod@verify), measured by `checks`), and two bakes of one scene compared at
//! surface points whatever their layouts (`agreement`: an incremental bake against a full one,
//! after the edits of `edit_cases`).

// The path tracer, the checks and the scoring at points take the stages' ray scene: public
// with the `internals` feature (most of `edges` and `points` serves the tests and the
// benchmarks; `verify` and `study` use the rest).
internal!(agreement, checks, edges, edit_cases, points, reference);
pub mod study;
pub mod verify;
