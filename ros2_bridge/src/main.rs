//! `stereosplat-ros2-bridge CONFIG.json5`: a zenoh runtime with the zenoh project's ROS 2 /
//! DDS plugin (`zenoh-plugin-ros2dds`) linked in, as the project's own
//! `zenoh-bridge-ros2dds` does: DDS publishers of ROS 2 nodes become zenoh publications on
//! `<topic without its leading slash>` and zenoh publications become DDS data for ROS 2
//! subscribers, payloads as CDR with their encapsulation header, the same bytes the
//! StereoSplat node sends and reads in its plain key mode. Everything (zenoh endpoints, the
//! plugin's `ros2dds` section, Cyclone DDS through `CYCLONEDDS_URI`) comes from the
//! configuration file and the environment; see `launch/ros2_bridge.json5`.

use anyhow::{anyhow, Context};
use zenoh::config::Config;
use zenoh::internal::plugins::PluginsManager;
use zenoh::internal::runtime::RuntimeBuilder;
use zenoh_config::ModeDependentValue;

#[tokio::main]
async fn main() -> anyhow::Result<()> {
    zenoh::init_log_from_env_or("z=warn");
    let path = std::env::args()
        .nth(1)
        .context("usage: stereosplat-ros2-bridge CONFIG.json5")?;
    let mut config = Config::from_file(&path)
        .map_err(|e| anyhow!("reading the bridge configuration {path}: {e}"))?;
    // Timestamps on every publication (the plugin's cache for transient-local topics needs
    // them), and the plugins of this binary allowed to start.
    config
        .timestamping
        .set_enabled(Some(ModeDependentValue::Unique(true)))
        .map_err(|e| anyhow!("{e:?}"))?;
    config
        .plugins_loading
        .set_enabled(true)
        .map_err(|e| anyhow!("{e:?}"))?;
    let mut plugins = PluginsManager::static_plugins_only();
    plugins.declare_static_plugin::<zenoh_plugin_ros2dds::ROS2Plugin, &str>("ros2dds", true);
    let mut runtime = RuntimeBuilder::new(config)
        .plugins_manager(plugins)
        .build()
        .await
        .map_err(|e| anyhow!("starting the zenoh runtime: {e}"))?;
    runtime
        .start()
        .await
        .map_err(|e| anyhow!("starting the zenoh runtime: {e}"))?;
    println!("bridge ready");
    tokio::signal::ctrl_c().await?;
    Ok(())
}
