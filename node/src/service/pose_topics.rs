//! The `/tf` and `/tf_static` subscriptions of a node whose poses come from a pose source
//! (`run --pose-source tf|odometry`). They live outside the node's namespace (tf2's
//! absolute topics), so the namespace's input subscriber does not see them; the odometry
//! topic does lie in it. Samples the node publishes itself (its own bin frames) are not
//! delivered.
//!
//! `/tf_static` is latched in ROS 2 (a `TRANSIENT_LOCAL` writer: `robot_state_publisher`
//! sends the mounts once, at its start, usually before the node's). The zenoh ROS 2 bridge
//! routes such a writer through a zenoh-ext advanced publisher that caches its samples, so
//! the node subscribes to `/tf_static` with an advanced subscriber that asks every such
//! cache for its history when it starts and whenever a publisher appears later
//! (`detect_late_publishers`): a mount published before the node started still arrives. A
//! plain zenoh publisher has no cache; its statics arrive only when it sends them again.

use zenoh::handlers::FifoChannelHandler;
use zenoh::pubsub::Subscriber;
use zenoh::sample::{Locality, Sample};
use zenoh::Session;
use zenoh_ext::{AdvancedSubscriber, AdvancedSubscriberBuilderExt, HistoryConfig};

use crate::transport::keys::{Keys, Topic, TF, TF_STATIC};
use crate::transport::TransportError;

/// The two subscriptions.
pub(super) struct PoseTopics {
    tf: Subscriber<FifoChannelHandler<Sample>>,
    tf_static: AdvancedSubscriber<FifoChannelHandler<Sample>>,
}

impl PoseTopics {
    /// Subscribes to `/tf` and `/tf_static` (with the publishers' cached history) under
    /// `keys`' mode.
    pub async fn declare(session: &Session, keys: &Keys) -> Result<Self, TransportError> {
        let tf = session
            .declare_subscriber(keys.key(TF))
            .allowed_origin(Locality::Remote)
            .await
            .map_err(TransportError::from)?;
        let tf_static = session
            .declare_subscriber(keys.key(TF_STATIC))
            .history(HistoryConfig::default().detect_late_publishers())
            .allowed_origin(Locality::Remote)
            .await
            .map_err(TransportError::from)?;
        Ok(Self { tf, tf_static })
    }

    /// The next sample on either topic, with its topic; pending for ever without `topics`
    /// (a node taking its poses from the `pose` topic) or once both subscriptions closed.
    pub async fn next(topics: Option<&Self>) -> (Topic, Sample) {
        let Some(t) = topics else {
            return std::future::pending().await;
        };
        tokio::select! {
            Ok(s) = t.tf.recv_async() => (TF, s),
            Ok(s) = t.tf_static.recv_async() => (TF_STATIC, s),
            else => std::future::pending().await,
        }
    }
}
