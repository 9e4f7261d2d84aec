//! The `/tf` and `/tf_static` subscriptions of a node whose poses come from a pose source
//! (`run --pose-source tf|odometry`). They live outside the node's namespace (tf2's
//! absolute topics), so the namespace's input subscriber does not see them; the odometry
//! topic does lie in it. Samples the node publishes itself (its own bin frames) are not
//! delivered.
//!
//! `/tf_static` is subscribed as samples arrive: a mount published once before the node
//! started (a latched `robot_state_publisher`) is received only when it is published again,
//! as tf2 broadcasters on zenoh without a publication cache do.

use zenoh::handlers::FifoChannelHandler;
use zenoh::pubsub::Subscriber;
use zenoh::sample::{Locality, Sample};
use zenoh::Session;

use super::keys::{Keys, Topic, TF, TF_STATIC};
use crate::transport::TransportError;

/// The two subscriptions.
pub(super) struct PoseTopics {
    tf: Subscriber<FifoChannelHandler<Sample>>,
    tf_static: Subscriber<FifoChannelHandler<Sample>>,
}

impl PoseTopics {
    /// Subscribes to `/tf` and `/tf_static` under `keys`' mode.
    pub async fn declare(session: &Session, keys: &Keys) -> Result<Self, TransportError> {
        let subscribe = |topic: Topic| {
            session
                .declare_subscriber(keys.key(topic))
                .allowed_origin(Locality::Remote)
        };
        let err = |e: zenoh::Error| TransportError::Zenoh(e.to_string());
        Ok(Self {
            tf: subscribe(TF).await.map_err(err)?,
            tf_static: subscribe(TF_STATIC).await.map_err(err)?,
        })
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
