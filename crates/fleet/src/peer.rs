//! Opening a Zenoh peer: explicit `tcp/...` listen and connect endpoints, multicast scouting
//! off, so a peer talks only to the endpoints it is given (on a LAN, a robot's address; in the
//! tests, `127.0.0.1`).

use crate::FleetError;
use zenoh::Wait;

/// Where a peer listens and whom it connects to.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct PeerConfig {
    /// Endpoints to listen on, e.g. `tcp/127.0.0.1:7447`.
    pub listen: Vec<String>,
    /// Endpoints of other peers to connect to.
    pub connect: Vec<String>,
}

impl PeerConfig {
    /// The Zenoh configuration: peer mode, the endpoints, multicast scouting off.
    ///
    /// ```
    /// let config = slamkit_fleet::PeerConfig {
    ///     listen: vec!["tcp/127.0.0.1:7447".into()],
    ///     connect: Vec::new(),
    /// };
    /// assert!(config.zenoh_config().is_ok());
    /// ```
    ///
    /// # Errors
    /// [`FleetError::Zenoh`] for an endpoint Zenoh does not accept.
    pub fn zenoh_config(&self) -> Result<zenoh::Config, FleetError> {
        let list = |endpoints: &[String]| {
            serde_json::to_string(endpoints).map_err(|e| FleetError::Zenoh(e.to_string()))
        };
        let mut config = zenoh::Config::default();
        for (key, value) in [
            ("mode", "\"peer\"".to_string()),
            ("scouting/multicast/enabled", "false".to_string()),
            ("listen/endpoints", list(&self.listen)?),
            ("connect/endpoints", list(&self.connect)?),
        ] {
            config
                .insert_json5(key, &value)
                .map_err(FleetError::zenoh)?;
        }
        Ok(config)
    }

    /// Opens a Zenoh session with this configuration.
    ///
    /// # Errors
    /// [`FleetError::Zenoh`] when Zenoh cannot open it (an endpoint taken, say).
    pub fn open(&self) -> Result<zenoh::Session, FleetError> {
        zenoh::open(self.zenoh_config()?)
            .wait()
            .map_err(FleetError::zenoh)
    }
}
