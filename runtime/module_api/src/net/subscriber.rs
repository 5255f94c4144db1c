//! The subscriber's side of data connections: an input linked to its provider (looked up,
//! connected, subscribed, sharing a connection the provider opened when it can), the
//! provider's answers, and relinking when it goes away.

use super::*;

impl Net {
    /// Drops the current link of an input and looks its provider up again.
    pub fn relink(&mut self, core: &mut Core, input: usize) {
        if let Some(InputLink::Connecting(token) | InputLink::Linked(token)) =
            self.inputs.get(input).copied()
        {
            self.inputs[input] = InputLink::Unbound;
            self.unsubscribe(core, token);
        }
        if let Some(link) = self.inputs.get_mut(input) {
            *link = resolve_or_unbound(&core.inputs[input]);
        }
    }

    /// Subscribes input `index` to the provider `advert` tells of: on a connection that
    /// provider already has with this module (it subscribed here) if that carries no input yet,
    /// else on a new one.
    pub(super) fn connect_input(&mut self, core: &mut Core, index: usize, advert: &Advert) {
        let retry = InputLink::Resolve {
            at: Instant::now() + RELINK_DELAY,
        };
        let Ok(addr) = advert.addr.parse::<SocketAddr>() else {
            tracing::warn!(addr = advert.addr, "agent gave an unreadable address");
            self.inputs[index] = retry;
            return;
        };
        // A subscribe from that provider may be waiting on a connection not accepted yet.
        self.accept_all(core);
        let shared = self
            .conns
            .iter()
            .find_map(|(&token, conn)| match conn.role {
                Role::Peer(PeerLink {
                    input: None,
                    peer_addr: Some(peer),
                    ..
                }) if peer == addr => Some(token),
                _ => None,
            });
        if shared.is_none() && self.awaits_identification() {
            // At most IDENTIFY_WAIT_MAX in all, whoever keeps connecting.
            let since = *self
                .identify_since
                .entry(index)
                .or_insert_with(Instant::now);
            if since.elapsed() < IDENTIFY_WAIT_MAX {
                self.inputs[index] = InputLink::Resolve {
                    at: Instant::now() + IDENTIFY_POLL,
                };
                return;
            }
        }
        self.identify_since.remove(&index);
        let ticket = match (&self.credentials, &advert.key) {
            (None, _) => None,
            (Some(_), Some(key)) => match Key::from_hex(key) {
                Some(key) => Some(key),
                None => {
                    tracing::warn!(
                        data_name = advert.data_name,
                        "agent gave an unreadable link key"
                    );
                    self.inputs[index] = retry;
                    return;
                }
            },
            (Some(_), None) => {
                tracing::warn!(
                    data_name = advert.data_name,
                    "the agent gave no link key for this provider (does it run with the secret?)"
                );
                self.inputs[index] = retry;
                return;
            }
        };
        // Kept: a subscription on a connection the provider opened proves it.
        if let Some(ticket) = &ticket {
            self.tickets.insert(index, ticket.clone());
        }
        let token = match shared {
            Some(token) => token,
            None => match self.open(
                addr,
                Role::Peer(PeerLink {
                    peer_addr: Some(addr),
                    ..PeerLink::default()
                }),
                ticket,
            ) {
                Ok(token) => {
                    if let Some(conn) = self.conns.get_mut(&token) {
                        conn.peer = self
                            .credentials
                            .as_ref()
                            .and(advert.data_name.split_once('.'))
                            .map(|(module, _)| module.to_owned());
                    }
                    token
                }
                Err(err) => {
                    tracing::debug!(%addr, "cannot connect to provider: {err}");
                    self.inputs[index] = retry;
                    return;
                }
            },
        };
        let slot = &mut core.inputs[index];
        if slot.raw {
            // A raw input takes whatever its provider serves.
            slot.data_type.clone_from(&advert.data_type);
        }
        self.subscribe_on(core, token, index);
    }

    /// Whether, with a shared secret, a peer whose first handshake message proved a key less
    /// than [`IDENTIFY_WAIT`] ago has not subscribed yet (it is in the middle of the
    /// handshake). A connection that has sent nothing valid, a stranger's, never counts; the
    /// wait is bounded in all by [`IDENTIFY_WAIT_MAX`].
    pub(super) fn awaits_identification(&self) -> bool {
        let now = Instant::now();
        self.credentials.is_some()
            && self.conns.values().any(|conn| {
                matches!(
                    conn.role,
                    Role::Peer(PeerLink {
                        input: None,
                        serving: None,
                        peer_addr: None,
                        ..
                    })
                ) && conn.identify_by.is_some_and(|until| until > now)
            })
    }

    /// Sends the subscribe of input `index` on `token`, which then feeds it.
    pub(super) fn subscribe_on(&mut self, core: &Core, token: Token, index: usize) {
        let slot = &core.inputs[index];
        // On a connection the provider opened, the link key it proved was for the other
        // direction: this one is proven by the ticket the agent gave for it.
        let proof = self
            .conns
            .get(&token)
            .filter(|conn| !conn.dialed)
            .and_then(|conn| conn.binding.as_deref())
            .zip(self.tickets.get(&index))
            .map(|(binding, ticket)| crate::auth::reverse_proof(ticket, binding));
        let subscribe = ToProvider::Subscribe {
            proof,
            data_name: slot.source.clone().unwrap_or_default(),
            data_type: slot.data_type.clone(),
            subscriber: format!("{}.{}", core.name, slot.name),
            reliable: slot.reliable,
            max_rate_hz: slot.max_rate_hz,
            pull: slot.pull,
            subscriber_addr: Some(self.listen_addr.to_string()),
        };
        self.queue_message(token, &subscribe);
        if let Some(conn) = self.conns.get_mut(&token) {
            if let Role::Peer(link) = &mut conn.role {
                link.input = Some(index);
            }
            // Out at once: a peer subscribing here at the same moment sees this first (see
            // `join_peer_connection`). A failed write shows at the next poll.
            let _ = conn.flush();
        }
        self.inputs[index] = InputLink::Connecting(token);
    }

    /// The provider's answer to the subscribe of input `index`.
    pub(super) fn on_answer(
        &mut self,
        core: &mut Core,
        token: Token,
        index: usize,
        answer: FromProvider,
    ) {
        match answer {
            FromProvider::Subscribed => {
                if self.joined_peer_connection(core, token, index) {
                    return;
                }
                core.inputs[index].link += 1;
                tracing::info!(
                    input = core.inputs[index].name,
                    source = core.inputs[index].source.as_deref().unwrap_or_default(),
                    "input linked"
                );
                self.inputs[index] = InputLink::Linked(token);
            }
            FromProvider::Refused { reason } => {
                tracing::warn!(
                    input = core.inputs[index].name,
                    "provider refused: {reason}"
                );
                self.drop_input_link(token);
                self.inputs[index] = InputLink::Resolve {
                    at: Instant::now() + Duration::from_secs(1),
                };
            }
            // Taken in `on_peer`, since it answers no subscription.
            FromProvider::Unsubscribed => {}
        }
    }

    /// The input fed on `token` is given up: a connection that also serves the peer stays up
    /// (the peer is asked to stop sending, and what it sent meanwhile is dropped); any other
    /// closes.
    pub(super) fn unsubscribe(&mut self, core: &mut Core, token: Token) {
        let Some(conn) = self.conns.get_mut(&token) else {
            return;
        };
        let Role::Peer(link) = &mut conn.role else {
            return;
        };
        if link.serving.is_none() {
            self.close(core, token);
            return;
        }
        link.input = None;
        link.unsubscribing = link.unsubscribing.saturating_add(1);
        // A reliable input that stopped reading holds nothing back any more: what the peer
        // sent is read now (and dropped), or the answer could wait behind it for ever.
        let paused = std::mem::take(&mut conn.paused);
        self.queue_message(token, &ToProvider::Unsubscribe);
        if paused {
            self.read_conn(core, token, UntilBlocked::Always);
        }
    }

    /// The connection `token` no longer feeds an input: closed, unless it serves the peer.
    pub(super) fn drop_input_link(&mut self, token: Token) {
        match self.conns.get_mut(&token).map(|conn| &mut conn.role) {
            Some(Role::Peer(link)) if link.serving.is_some() => link.input = None,
            _ => {
                self.remove_conn(token);
            }
        }
    }

    /// Asks the provider of `input` for its latest sample; `false` if it is not linked.
    pub fn pull(&mut self, input: usize) -> bool {
        let Some(InputLink::Linked(token)) = self.inputs.get(input).copied() else {
            return false;
        };
        self.queue_message(token, &ToProvider::Pull);
        true
    }

    /// Input `index` is answered on `token`, a connection this module opened: if the peer
    /// subscribed here on a connection of its own in the meantime (sent before this answer, so
    /// already pending), the input moves to that one, and `true` is returned.
    pub(super) fn joined_peer_connection(
        &mut self,
        core: &mut Core,
        token: Token,
        index: usize,
    ) -> bool {
        let peer_addr = match self.conns.get(&token).map(|conn| conn.role) {
            Some(Role::Peer(PeerLink {
                serving: None,
                peer_addr: Some(addr),
                ..
            })) => addr,
            _ => return false,
        };
        if self.listen_addr <= peer_addr {
            return false;
        }
        self.accept_all(core);
        self.inputs[index] != InputLink::Connecting(token)
    }

    /// Two modules that subscribe to each other at the same moment open a connection each.
    /// Both see the peer's subscribe arrive on the peer's connection; the one with the higher
    /// data address then gives its own connection up, if its subscription there is still
    /// unanswered (so no sample of it has been taken), and subscribes again on the peer's.
    /// The other keeps its own, so both choose the same connection.
    pub(super) fn join_peer_connection(
        &mut self,
        core: &Core,
        token: Token,
        peer_addr: SocketAddr,
    ) {
        let free = matches!(
            self.conns.get(&token).map(|conn| conn.role),
            Some(Role::Peer(PeerLink { input: None, .. }))
        );
        if self.listen_addr <= peer_addr || !free {
            return;
        }
        let own = self
            .conns
            .iter()
            .find_map(|(&other, conn)| match conn.role {
                Role::Peer(PeerLink {
                    input: Some(index),
                    serving: None,
                    peer_addr: Some(addr),
                    ..
                }) if other != token
                    && addr == peer_addr
                    && self.inputs[index] == InputLink::Connecting(other) =>
                {
                    Some((other, index))
                }
                _ => None,
            });
        if let Some((other, index)) = own {
            self.remove_conn(other);
            self.subscribe_on(core, token, index);
        }
    }

    pub fn is_linked(&self, input: usize) -> bool {
        matches!(self.inputs.get(input), Some(InputLink::Linked(_)))
    }
}
