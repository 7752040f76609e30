//! Analysis: the brute-force path tracer that error measurements compare against
//! ([`reference`](mod@reference)), bakes of any layout scored against it at surface points
//! ([`points`]) and densely next to contacts and seams ([`edges`]), and the convergence study
//! of error against run time ([`study`]), and a finished bake checked against the path tracer
//! (`bake --verify`, [`verify`](mod@verify)).

pub mod edges;
pub mod points;
pub mod reference;
pub mod study;
pub mod verify;
