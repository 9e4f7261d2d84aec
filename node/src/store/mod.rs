//! The global map on disk: its base, journal and tile files in the node's out folder, what
//! a restart resumes from and what the node exports when it stops ([`map_files`]), and the
//! store that writes each bin's record ahead of its publication ([`map_store`]).

pub mod map_files;
pub mod map_store;

pub use map_files::{settings_kept, ExportError, RestoreError, SettingKept, StartMap};
pub use map_store::{Compaction, Paging};
