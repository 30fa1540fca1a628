//! Every integration test of this crate in one binary (one link instead of one per file).

mod batch_refine;
mod blemishes;
mod bundled;
mod clean_failures;
mod cli;
mod eveh;
mod failures_cli;
mod gate;
mod generate;
mod libraries;
mod log_cli;
mod low_rate;
mod ode;
mod plot;
mod quality;
mod recording;
mod refine_supports;
mod replay_cli;
mod replay_link;
mod replay_resume;
mod spikes;
mod standard_errors;
mod stream;
mod sweep;
mod telemetry_fuzz;
mod track;
