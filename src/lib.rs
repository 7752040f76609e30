//! Workspace-level tests, benchmarks and examples for lightbake.
