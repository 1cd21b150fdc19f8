//! The daemon's network side: the QUIC server on its own runtime.

use std::net::SocketAddr;
use std::sync::Arc;

use rt::Shutdown;

use super::{DaemonError, RunConfig, io};
use crate::net;

/// The network side: its runtime and the QUIC server serving the loop's hand-off.
pub(super) struct Network {
    pub(super) runtime: tokio::runtime::Runtime,
    pub(super) server: tokio::task::JoinHandle<()>,
    pub(super) net_stop: Shutdown,
    pub(super) addr: SocketAddr,
    pub(super) pins: Arc<transport::OperatorPins>,
}

impl Network {
    /// Binds the server on its own runtime and starts serving `net_io`.
    pub(super) fn start(config: &RunConfig, net_io: net::NetIo) -> Result<Network, DaemonError> {
        let runtime =
            transport::network_runtime("telerobot-net").map_err(io("the network runtime"))?;
        let server = {
            let _entered = runtime.enter();
            net::bind(config.net_config())?
        };
        let addr = server
            .local_addr()
            .map_err(io("the server's local address"))?;
        let pins = server.pins();
        let net_stop = Shutdown::new();
        let server = {
            let stop = net_stop.clone();
            runtime.spawn(async move { server.serve(net_io, stop.wait()).await })
        };
        for (path, _) in &config.trusted_operators {
            tracing::info!(file = %path.display(), "trusting operator certificate");
        }
        Ok(Network {
            runtime,
            server,
            net_stop,
            addr,
            pins,
        })
    }
}
