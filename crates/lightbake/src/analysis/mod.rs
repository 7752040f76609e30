//! Analysis: the brute-force path tracer that error measurements compare against
//! ([`reference`](mod@reference)), and the convergence study of error against run time ([`study`]).

pub mod reference;
pub mod study;
