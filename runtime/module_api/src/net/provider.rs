//! The provider's side of data connections: samples published to subscribers (batched, rate
//! limited, or written from the publisher's own buffer when large), subscriptions taken and
//! given up, and pulls answered from the latest frame.

use super::*;

impl Net {
    /// Sends a frame, given in `parts` (the whole frame, or a header and the caller's payload),
    /// to every subscriber of `output`.
    pub fn publish(
        &mut self,
        core: &mut Core,
        output: usize,
        parts: &[&[u8]],
    ) -> Result<(), ApiError> {
        let frame_len: usize = parts.iter().map(|part| part.len()).sum();
        let mut stalled = Vec::new();
        let mut unfinished = Vec::new();
        let mut now = None;
        for &token in &self.subscribers[output] {
            let Some(conn) = self.conns.get_mut(&token) else {
                continue;
            };
            let Role::Peer(PeerLink {
                serving:
                    Some(Serving {
                        reliable,
                        min_interval,
                        pull,
                        ..
                    }),
                ..
            }) = conn.role
            else {
                continue;
            };
            // A pull subscriber gets a sample only when it asked before there was one; a
            // failed write shows as the connection's error at the next poll.
            let pulled = std::mem::take(&mut conn.pull_pending);
            if pull {
                if pulled {
                    conn.out.push_frame_parts(parts, false);
                    let _ = conn.flush();
                }
                continue;
            }
            if let Some(min_interval) = min_interval {
                let now = *now.get_or_insert_with(Instant::now);
                if conn
                    .last_sent
                    .is_some_and(|last| now.saturating_duration_since(last) < min_interval)
                {
                    continue;
                }
                conn.last_sent = Some(now);
            }
            if reliable && frame_len >= BATCH_BYTES {
                conn.make_room_for(frame_len);
            }
            if reliable
                && conn.out.is_empty()
                && frame_len >= BATCH_BYTES
                && conn.link.is_sealing()
                && conn.link.seal_frame(parts)
            {
                // An encrypted link: the frame is sealed from the caller's buffers into the
                // records that wait for the socket.
                if let Err(err) = conn.link.flush_pending()
                    && err.kind() != ErrorKind::WouldBlock
                {
                    stalled.push(token);
                    continue;
                }
            } else if reliable
                && conn.out.is_empty()
                && frame_len >= BATCH_BYTES
                && !conn.link.is_sealing()
            {
                // A large frame with nothing queued before it goes out from the caller's
                // buffers, all of it: what the socket does not take now is written as it drains
                // (`finish_large_frame`), as a blocking write would, rather than copied. (A
                // best-effort subscriber's queue may drop frames not yet started, so its frames
                // are always queued whole.)
                let slices: Vec<std::io::IoSlice<'_>> = parts
                    .iter()
                    .map(|part| std::io::IoSlice::new(part))
                    .collect();
                match std::io::Write::write_vectored(conn.stream(), &slices) {
                    Ok(written) if written == frame_len => {}
                    Ok(written) => {
                        conn.writing_parts = true;
                        unfinished.push((token, written));
                    }
                    Err(err) if err.kind() == ErrorKind::WouldBlock => {
                        conn.writing_parts = true;
                        unfinished.push((token, 0));
                    }
                    Err(_) => stalled.push(token),
                }
                continue;
            } else {
                conn.out.push_frame_parts(parts, !reliable);
            }
            let large_left = reliable && frame_len >= BATCH_BYTES && conn.pending_bytes() > 0;
            if large_left || conn.out.pending_bytes() >= BATCH_BYTES {
                match conn.flush() {
                    Ok(_) if reliable && conn.pending_bytes() > backlog_limit(frame_len) => {
                        stalled.push(token)
                    }
                    Ok(_) => {}
                    Err(_) => stalled.push(token),
                }
            }
        }
        for (token, written) in unfinished {
            self.finish_large_frame(core, token, parts, written)?;
        }
        for token in stalled {
            self.wait_for_subscriber(core, token, backlog_limit(frame_len))?;
        }
        Ok(())
    }

    /// Writes the rest of a large frame (`parts`, of which `written` bytes went out) from the
    /// publisher's buffers as the socket takes it, keeping the loop turning meanwhile (other
    /// connections, this one's reads) as [`Net::wait_for_subscriber`] does; nothing else is
    /// written to this socket until the frame is whole. A subscriber stuck for
    /// [`RELIABLE_STALL`] is dropped.
    pub(super) fn finish_large_frame(
        &mut self,
        core: &mut Core,
        token: Token,
        parts: &[&[u8]],
        mut written: usize,
    ) -> Result<(), ApiError> {
        let frame_len: usize = parts.iter().map(|part| part.len()).sum();
        let give_up = Instant::now() + RELIABLE_STALL;
        loop {
            let Some(conn) = self.conns.get_mut(&token) else {
                return Ok(());
            };
            let rest = unwritten(parts, written);
            let slices: Vec<std::io::IoSlice<'_>> = rest
                .iter()
                .map(|part| std::io::IoSlice::new(part))
                .collect();
            match std::io::Write::write_vectored(conn.stream(), &slices) {
                Ok(0) => {}
                Ok(more) => {
                    written += more;
                    if written >= frame_len {
                        conn.writing_parts = false;
                        // What was queued for this connection meanwhile (answers) follows.
                        if let Err(err) = conn.flush() {
                            tracing::info!("subscriber went away: {err}");
                            self.close(core, token);
                        }
                        return Ok(());
                    }
                    continue;
                }
                Err(err) if err.kind() == ErrorKind::WouldBlock => {}
                Err(err) if err.kind() == ErrorKind::Interrupted => continue,
                Err(err) => {
                    tracing::info!("subscriber went away: {err}");
                    conn.writing_parts = false;
                    self.close(core, token);
                    return Ok(());
                }
            }
            if Instant::now() >= give_up {
                tracing::warn!(
                    "a reliable subscriber has not read for {RELIABLE_STALL:?}; dropping it"
                );
                conn.writing_parts = false;
                self.close(core, token);
                return Ok(());
            }
            // Wait for the socket to drain even when the module has events waiting (the loop
            // turns without waiting then): they are kept, first, for its next `next_event`.
            let waiting = std::mem::take(&mut core.events);
            let polled = self.poll_once(core, Some(Instant::now() + Duration::from_millis(50)));
            let arrived = std::mem::replace(&mut core.events, waiting);
            core.events.extend(arrived);
            if let Err(err) = polled {
                // Half a frame went out: the connection cannot carry anything else.
                self.close(core, token);
                return Err(err);
            }
        }
    }

    /// Back-pressure for a reliable subscriber: keep the loop turning (other connections too)
    /// until its backlog drains, or drop it if it stays stuck.
    pub(super) fn wait_for_subscriber(
        &mut self,
        core: &mut Core,
        token: Token,
        limit: usize,
    ) -> Result<(), ApiError> {
        let give_up = Instant::now() + RELIABLE_STALL;
        loop {
            let Some(conn) = self.conns.get_mut(&token) else {
                return Ok(());
            };
            match conn.flush() {
                Ok(_) if conn.pending_bytes() <= limit => return Ok(()),
                Ok(_) => {}
                Err(err) => {
                    tracing::info!("subscriber went away: {err}");
                    self.close(core, token);
                    return Ok(());
                }
            }
            if Instant::now() >= give_up {
                tracing::warn!(
                    "a reliable subscriber has not read for {RELIABLE_STALL:?}; dropping it"
                );
                self.close(core, token);
                return Ok(());
            }
            self.poll_once(core, Some(Instant::now() + Duration::from_millis(50)))?;
        }
    }

    /// A subscriber asks for the latest sample of `output`: written now if there is one, else
    /// the next one sent.
    pub(super) fn on_pull(&mut self, token: Token, output: usize) {
        if self.pulled.len() <= output {
            self.pulled.resize(output + 1, false);
        }
        self.pulled[output] = true;
        let Some(conn) = self.conns.get_mut(&token) else {
            return;
        };
        match self.latest.get(output).filter(|frame| !frame.is_empty()) {
            Some(frame) => {
                conn.out.push_frame(frame, false);
                // A failed write shows as the connection's error at the next poll.
                let _ = conn.flush();
            }
            None => conn.pull_pending = true,
        }
    }

    /// Whether the latest frame of `output` is worth a copy: it has a pull-mode subscriber, or
    /// was pulled before. (A frame encoded in the node's buffer is kept anyway, by a swap.)
    pub(super) fn wants_latest_copy(&self, output: usize) -> bool {
        self.pulled.get(output).copied().unwrap_or(false)
            || self.subscribers[output].iter().any(|token| {
                self.conns.get(token).is_some_and(|conn| {
                    matches!(
                        conn.role,
                        Role::Peer(PeerLink {
                            serving: Some(Serving { pull: true, .. }),
                            ..
                        })
                    )
                })
            })
    }

    /// Keeps the frame in `parts`, just published on `output`, as its latest: copied if
    /// [`Net::wants_latest_copy`], else none is kept (a pull then gets the next one).
    pub fn keep_latest_parts(&mut self, output: usize, parts: &[&[u8]]) {
        let copy = self.wants_latest_copy(output);
        if self.latest.len() <= output {
            self.latest.resize_with(output + 1, Vec::new);
        }
        let latest = &mut self.latest[output];
        latest.clear();
        if copy {
            for part in parts {
                latest.extend_from_slice(part);
            }
        }
    }

    /// Keeps `frame`, just published on `output`, as its latest (taking the buffer and giving
    /// back the previous one, cleared).
    pub fn keep_latest(&mut self, output: usize, frame: &mut Vec<u8>) {
        if self.latest.len() <= output {
            self.latest.resize_with(output + 1, Vec::new);
        }
        std::mem::swap(&mut self.latest[output], frame);
        frame.clear();
    }

    pub(super) fn on_subscribe(&mut self, core: &mut Core, token: Token, message: ToProvider) {
        let ToProvider::Subscribe {
            data_name,
            data_type,
            subscriber,
            reliable,
            max_rate_hz,
            pull,
            subscriber_addr,
            proof,
        } = message
        else {
            return;
        };
        // With a secret, a subscription on a connection this module opened comes from the
        // provider it dialled, whose link key was issued for the other direction: it must
        // prove the one the agent issued it for this module's port.
        let unproven_reverse = match (&self.credentials, self.conns.get(&token)) {
            (Some(credentials), Some(conn)) if conn.dialed => {
                let binding = conn.binding.as_deref().unwrap_or_default();
                let peer = conn.peer.as_deref().unwrap_or_default();
                let ticket = credentials.key.link_key(peer);
                !proof
                    .is_some_and(|proof| crate::auth::check_reverse_proof(&ticket, binding, &proof))
            }
            _ => false,
        };
        // A reliable subscriber takes every sample; a rate that is not a positive number is
        // no limit.
        let min_interval = max_rate_hz
            .filter(|rate| !reliable && rate.is_finite() && *rate > 0.0)
            .and_then(|rate| Duration::try_from_secs_f64(1.0 / rate).ok());
        let found = core
            .outputs
            .iter()
            .position(|slot| slot.data_name == data_name);
        let proven = self.conns.get(&token).and_then(|conn| conn.peer.clone());
        let refusal = match found {
            _ if unproven_reverse => Some(format!(
                "`{subscriber}` subscribes back on a connection `{}` opened, without the link \
                 key for this direction (the agent gives it only to who may subscribe)",
                core.name
            )),
            // With a secret, a subscriber's name is its proven module's.
            _ if proven.as_ref().is_some_and(|module| {
                subscriber.split_once('.').map(|(name, _)| name) != Some(module.as_str())
            }) =>
            {
                Some(format!(
                    "`{subscriber}` is not an input of `{}`, which this connection proved to be",
                    proven.unwrap_or_default()
                ))
            }
            None => Some(format!("`{}` does not serve `{data_name}`", core.name)),
            Some(output) if core.outputs[output].data_type != data_type => Some(format!(
                "`{data_name}` carries {}, not {data_type}",
                core.outputs[output].data_type
            )),
            Some(_) => None,
        };
        let reply = match &refusal {
            Some(reason) => FromProvider::Refused {
                reason: reason.clone(),
            },
            None => FromProvider::Subscribed,
        };
        self.queue_message(token, &reply);
        let Some(conn) = self.conns.get_mut(&token) else {
            return;
        };
        let _ = conn.flush();
        let Role::Peer(link) = &mut conn.role else {
            return;
        };
        match (refusal, found) {
            (None, Some(output)) => {
                link.serving = Some(Serving {
                    output,
                    reliable,
                    min_interval,
                    pull,
                });
                let peer_addr = subscriber_addr.and_then(|addr| match addr.parse::<SocketAddr>() {
                    Ok(addr) => Some(addr),
                    Err(_) => {
                        tracing::warn!(subscriber, addr, "unreadable subscriber_addr: not shared");
                        None
                    }
                });
                if link.peer_addr.is_none() {
                    link.peer_addr = peer_addr;
                }
                conn.handshake_deadline = None;
                self.subscribers[output].push(token);
                tracing::info!(subscriber, data_name, "subscriber linked");
                if let Some(peer_addr) = peer_addr {
                    self.join_peer_connection(core, token, peer_addr);
                }
            }
            (refusal, _) => {
                tracing::warn!(subscriber, "refused: {}", refusal.unwrap_or_default());
                if link.input.is_none() {
                    self.remove_conn(token);
                }
            }
        }
    }

    /// The subscriber on `token` gives its subscription up: the connection stays for the other
    /// direction.
    pub(super) fn on_unsubscribe(&mut self, core: &Core, token: Token) {
        let Some(conn) = self.conns.get_mut(&token) else {
            return;
        };
        conn.pull_pending = false;
        conn.last_sent = None;
        if let Role::Peer(link) = &mut conn.role
            && let Some(Serving { output, .. }) = link.serving.take()
        {
            self.subscribers[output].retain(|&other| other != token);
            tracing::info!(output = core.outputs[output].name, "subscriber left");
        }
        self.queue_message(token, &FromProvider::Unsubscribed);
        self.close_if_idle(token);
    }

    pub fn subscriber_count(&self, output: usize) -> usize {
        self.subscribers.get(output).map_or(0, Vec::len)
    }
}

/// What is left of `parts` after its first `written` bytes.
fn unwritten<'a>(parts: &[&'a [u8]], mut written: usize) -> Vec<&'a [u8]> {
    let mut rest = Vec::with_capacity(parts.len());
    for part in parts {
        if written >= part.len() {
            written -= part.len();
        } else {
            rest.push(&part[written..]);
            written = 0;
        }
    }
    rest
}

/// How much a reliable subscriber may have queued before the publisher waits for it. Small
/// frames are batched up to [`RELIABLE_BACKLOG_BYTES`]; after a large one the publisher waits
/// until the queue is written, so that the next large frame goes out from the sender's buffer
/// instead of being copied behind it.
fn backlog_limit(frame_len: usize) -> usize {
    if frame_len >= BATCH_BYTES {
        0
    } else {
        RELIABLE_BACKLOG_BYTES
    }
}

#[cfg(test)]
#[allow(clippy::unwrap_used)]
mod tests {
    use super::*;

    #[test]
    pub(super) fn what_a_partial_write_leaves_is_the_rest_of_the_parts() {
        let parts: [&[u8]; 3] = [b"abc", b"de", b"fgh"];
        assert_eq!(unwritten(&parts, 0), parts);
        assert_eq!(unwritten(&parts, 2), [&b"c"[..], b"de", b"fgh"]);
        assert_eq!(unwritten(&parts, 3), [&b"de"[..], b"fgh"]);
        assert_eq!(unwritten(&parts, 6), [&b"gh"[..]]);
        assert!(unwritten(&parts, 8).is_empty());
    }

    #[test]
    pub(super) fn small_frames_batch_and_a_large_one_waits_for_the_queue_to_drain() {
        assert_eq!(backlog_limit(1), RELIABLE_BACKLOG_BYTES);
        assert_eq!(backlog_limit(BATCH_BYTES - 1), RELIABLE_BACKLOG_BYTES);
        assert_eq!(backlog_limit(BATCH_BYTES), 0);
        assert_eq!(backlog_limit(20 * 1024 * 1024), 0);
    }

    #[test]
    pub(super) fn a_data_connection_tells_requests_from_answers() {
        let read = |text: String| serde_json::from_str::<PeerMessage>(&text).unwrap();
        let pull = read(serde_json::to_string(&ToProvider::Pull).unwrap());
        assert!(matches!(pull, PeerMessage::Request(ToProvider::Pull)));
        let unsubscribed = read(serde_json::to_string(&FromProvider::Unsubscribed).unwrap());
        assert!(matches!(
            unsubscribed,
            PeerMessage::Answer(FromProvider::Unsubscribed)
        ));
    }
}
