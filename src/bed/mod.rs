//! Bed generation: particle size distributions ([`psd`]), random non-overlapping insertion in a
//! box ([`insertion`]), particles read from files ([`import`]) with their contacts' tangential
//! springs ([`contact_history`]) and deposition under gravity until the bed has settled
//! ([`deposition`]). `crate::model` calls these when it builds a scene's
//! `[[insert]]` and `[[import]]` blocks; `docs/scene-format.md` documents the keys.

pub mod contact_history;
pub mod deposition;
pub mod import;
pub mod insertion;
pub mod psd;
pub mod rng;
