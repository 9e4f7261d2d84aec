//! The answer to a snapshot query (`snapshot_request`): refused while the map's journal is
//! not durable (a crash could take back what a snapshot would show), for a malformed or
//! too large region, or beyond the requester's rate ([`SnapshotGate`]); otherwise the whole
//! map as one reply, or a region's Gaussians in pages, each with its attachment.

use std::time::Instant;

use zenoh::query::Query;

use super::error::ServiceError;
use super::fused_map::RegionPages;
use super::outputs::Outputs;
use super::region::RegionQuery;
use super::snapshot_gate::SnapshotGate;
use crate::msg::Message;
use crate::store::map_files::RegionReadError;
use crate::transport::TransportError;

/// Answers `q` from `outputs`' map, counting every refusal and encoding error.
pub(super) async fn answer_snapshot(
    q: Query,
    outputs: &mut Outputs<'_>,
    gate: &mut SnapshotGate,
) -> Result<(), ServiceError> {
    if !outputs.durable() {
        outputs.counters.add("refused/snapshot_not_durable", 1);
        let why = "the map's journal is not durable (disk full?): snapshots wait until it is";
        q.reply_err(why).await.map_err(TransportError::from)?;
        return Ok(());
    }
    let region = match RegionQuery::parse(q.parameters().iter()) {
        Ok(region) => region,
        Err(refused) => {
            outputs.counters.add("refused/snapshot_region", 1);
            q.reply_err(refused.to_string())
                .await
                .map_err(TransportError::from)?;
            return Ok(());
        }
    };
    if let Err(refused) = gate.admit(q.key_expr().as_str(), Instant::now()) {
        outputs.counters.add(refused.counter(), 1);
        q.reply_err(refused.to_string())
            .await
            .map_err(TransportError::from)?;
        return Ok(());
    }
    let Some(region) = region else {
        match outputs.fused.snapshot(outputs.snapshot_header()) {
            Ok(bytes) => q
                .reply(q.key_expr().clone(), bytes)
                .attachment(outputs.fused.snapshot_attachment())
                .await
                .map_err(TransportError::from)?,
            Err(_) => outputs.counters.add("error/encode_map_update", 1),
        }
        return Ok(());
    };
    let RegionPages { pages, total } = match outputs.fused.region_pages(&region) {
        Ok(pages) => pages,
        Err(e) => {
            let counter = match e {
                RegionReadError::TooLarge { .. } => "refused/snapshot_region",
                RegionReadError::Tile(_) => "error/region_tiles",
            };
            outputs.counters.add(counter, 1);
            q.reply_err(e.to_string())
                .await
                .map_err(TransportError::from)?;
            return Ok(());
        }
    };
    let count = pages.len();
    for (i, page) in pages.into_iter().enumerate() {
        let attachment = region.attachment(i, count, total);
        match outputs.fused.region_page(page, outputs.snapshot_header()) {
            Ok(m) => q
                .reply(q.key_expr().clone(), m.encode())
                .attachment(attachment)
                .await
                .map_err(TransportError::from)?,
            Err(_) => outputs.counters.add("error/encode_map_update", 1),
        }
    }
    Ok(())
}
