//! Bins fused into the map whose journal record is not yet durable (the disk is full, a
//! write or a sync failed): held back from publishing, in bin order, until the journal
//! takes them ([`crate::store::map_store::MapStore::flush`]), so that nothing the node publishes
//! can be lost by a crash.
//!
//! The hold is bounded: at most [`MAX_HELD_BINS`] bins (their maps and, once drawn, their
//! renders). A bin arriving while the hold is full is not fused and not published: it is
//! dropped and counted (`dropped/not_durable`), since it could not be kept either.

use std::collections::VecDeque;

use crate::fusion::Increment;
use crate::pipeline::worker::{Output, Rendered};

/// Bins held at most while the journal fails (each holds its map, a few MB at most).
pub const MAX_HELD_BINS: usize = 4;

/// A bin fused into the map (or one without a map), to publish once the journal is
/// durable up to it.
pub(super) struct FusedBin {
    /// What the worker made of the bin, its stamps up to the fusion.
    pub out: Output,
    /// The increment it made and the map's sequence number after it (`Err`: fusion
    /// refused it; `None`: the bin has no map).
    pub fused: Option<Result<(Increment, u64), ()>>,
    /// Its render, when it came while the bin was held.
    pub render: Option<Rendered>,
}

/// The held bins, oldest first.
#[derive(Default)]
pub(super) struct Held {
    bins: VecDeque<FusedBin>,
}

impl Held {
    /// Whether no bin is held (everything fused is published or publishable).
    pub fn is_empty(&self) -> bool {
        self.bins.is_empty()
    }

    /// Bins held.
    pub fn len(&self) -> usize {
        self.bins.len()
    }

    /// Whether another bin can be held.
    pub fn has_room(&self) -> bool {
        self.bins.len() < MAX_HELD_BINS
    }

    /// Holds `bin` after the others.
    pub fn push(&mut self, bin: FusedBin) {
        self.bins.push_back(bin);
    }

    /// Keeps `render` with its bin when that bin is held; gives it back otherwise.
    pub fn take_render(&mut self, render: Rendered) -> Option<Rendered> {
        match self.bins.iter_mut().find(|b| b.out.bin_id == render.bin_id) {
            Some(bin) => {
                bin.render = Some(render);
                None
            }
            None => Some(render),
        }
    }

    /// Every held bin, oldest first, leaving none.
    pub fn drain(&mut self) -> Vec<FusedBin> {
        self.bins.drain(..).collect()
    }
}
