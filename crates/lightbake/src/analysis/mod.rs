//! Analysis: the brute-force path tracer that error measurements compare against
//! (`reference`), bakes of any layout scored against it at surface points (`points`) and
//! densely next to contacts and seams (`edges`), the convergence study of error against run
//! time ([`study`]), and a finished bake checked against the path tracer (`bake --verify`,
//! [`verify`](mod@verify), measured by `checks`).

// The path tracer, the checks and the scoring at points take the stages' ray scene: public
// with the `internals` feature (most of `edges` and `points` serves the tests and the
// benchmarks; `verify` and `study` use the rest).
internal!(checks, edges, points, reference);
pub mod study;
pub mod verify;
