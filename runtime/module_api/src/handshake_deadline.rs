//! How long a listener waits for a connection's handshake: step by step, not for the whole.
//!
//! A stranger must be closed quickly, yet an operator or a module behind a slow radio link must
//! get in. The two are told apart by what the handshake needs of the link. The dialer's first
//! message (its hello and, with a secret, its first handshake message) goes out right behind
//! its connect, with no round trip before it: it reaches the listener about when the listener
//! accepts, however long the link's delay, so [`FIRST_MESSAGE_TIMEOUT`] is short and a
//! stranger that says nothing, or nothing valid, is closed within it. The rest of the handshake
//! (the listener's answer, then the dialer's confirmation) takes a round trip of the link:
//! once the first message proved a key, the peer gets [`CONFIRM_TIMEOUT`] more, long enough
//! for a round trip of several seconds on a congested radio, and never longer. Only a key
//! holder reaches that second step, and listeners drop a connection that has proved nothing
//! before one that has when they are full.

use std::time::{Duration, Instant};

/// How long a new connection has for its first message (the hello, and with a secret a valid
/// first handshake message).
pub const FIRST_MESSAGE_TIMEOUT: Duration = Duration::from_millis(1500);
/// How long a connection whose first message proved a key has for the rest of the handshake,
/// a round trip of the link.
pub const CONFIRM_TIMEOUT: Duration = Duration::from_secs(10);

/// When a connection in its handshake is closed, given its progress.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct HandshakeDeadline {
    at: Instant,
    proved: bool,
}

impl HandshakeDeadline {
    /// For a connection accepted at `now`.
    pub fn accepted(now: Instant) -> Self {
        Self {
            at: now + FIRST_MESSAGE_TIMEOUT,
            proved: false,
        }
    }

    /// The first message proved a key at `now`: the peer gets [`CONFIRM_TIMEOUT`] for the rest.
    /// Later calls change nothing, so that a peer cannot stretch its handshake step by step.
    pub fn proved(&mut self, now: Instant) {
        if !self.proved {
            self.proved = true;
            self.at = now + CONFIRM_TIMEOUT;
        }
    }

    /// Whether the first message proved a key.
    pub fn has_proved(&self) -> bool {
        self.proved
    }

    /// When the connection is closed if its handshake is not over.
    pub fn at(&self) -> Instant {
        self.at
    }

    /// Whether that moment has come.
    pub fn expired(&self, now: Instant) -> bool {
        self.at <= now
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_stranger_has_the_short_timeout_and_a_key_holder_one_round_trip_more() {
        let start = Instant::now();
        let mut deadline = HandshakeDeadline::accepted(start);
        assert!(!deadline.expired(start + FIRST_MESSAGE_TIMEOUT / 2));
        assert!(deadline.expired(start + FIRST_MESSAGE_TIMEOUT));
        let proved_at = start + Duration::from_millis(1000);
        deadline.proved(proved_at);
        assert!(deadline.has_proved());
        assert!(!deadline.expired(start + FIRST_MESSAGE_TIMEOUT));
        assert_eq!(deadline.at(), proved_at + CONFIRM_TIMEOUT);
        // A second proof does not push the deadline on.
        deadline.proved(proved_at + Duration::from_secs(5));
        assert_eq!(deadline.at(), proved_at + CONFIRM_TIMEOUT);
    }
}
