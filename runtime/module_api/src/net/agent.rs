//! The agent's and the supervisor's links: what this module registers, the lookups of its
//! inputs' providers, and the supervisor's configuration and the reports sent to it.

use super::*;

impl Net {
    /// Everything this module serves, for the agent (a registration replaces the previous one).
    pub(super) fn registration(&self, core: &Core) -> ToAgent {
        ToAgent::Register {
            module: core.name.clone(),
            outputs: core
                .outputs
                .iter()
                .map(|slot| Advert {
                    data_name: slot.data_name.clone(),
                    data_type: slot.data_type.clone(),
                    addr: self.listen_addr.to_string(),
                    key: None,
                })
                .collect(),
        }
    }

    pub(super) fn connect_agent(&mut self, core: &mut Core) {
        match self.open(self.agent_addr, Role::Agent, None) {
            Ok(token) => {
                self.agent = Link::Up(token);
                let register = self.registration(core);
                self.queue_message(token, &register);
                // Lookups that were waiting for the agent go out now.
                for link in &mut self.inputs {
                    if let InputLink::Asked { .. } = link {
                        *link = InputLink::Resolve { at: Instant::now() };
                    }
                }
            }
            Err(err) => {
                tracing::debug!(agent = %self.agent_addr, "cannot connect to the agent: {err}");
                self.agent = Link::Down {
                    retry_at: Instant::now() + AGENT_RETRY,
                };
            }
        }
    }

    /// A raw input was added to `core` at `index`: look its provider up.
    pub fn add_input(&mut self, core: &Core, index: usize) {
        debug_assert_eq!(index, self.inputs.len());
        self.inputs.push(resolve_or_unbound(&core.inputs[index]));
    }

    /// A raw output was added to `core` (last): register everything again, so that the agent
    /// knows it (if the agent is unreachable, the next connection registers it).
    pub fn add_output(&mut self, core: &Core) {
        self.subscribers.push(Vec::new());
        if let Link::Up(token) = self.agent {
            let register = self.registration(core);
            self.queue_message(token, &register);
        }
    }

    pub fn tell_supervisor(&mut self, message: &ToSupervisor) {
        match self.supervisor {
            Link::Up(token) => self.queue_message(token, message),
            Link::Down { .. } if self.supervisor_addr.is_some() => {
                tracing::warn!(?message, "supervisor unreachable; report lost");
            }
            Link::Down { .. } => tracing::debug!(?message, "no supervisor (standalone run)"),
        }
    }

    pub(super) fn on_agent(&mut self, core: &mut Core, message: FromAgent) {
        match message {
            FromAgent::Registered => {
                self.agent_lost_logged = false;
                tracing::debug!("registered with the agent");
            }
            FromAgent::Provider(advert) => {
                // An answer, or the agent telling of a provider asked for in vain before.
                for index in 0..self.inputs.len() {
                    let waiting = matches!(
                        self.inputs[index],
                        InputLink::Asked { .. } | InputLink::Resolve { .. }
                    ) && core.inputs[index].source.as_deref()
                        == Some(advert.data_name.as_str());
                    if waiting {
                        self.connect_input(core, index, &advert);
                    }
                }
            }
            FromAgent::Unknown { data_name } => {
                for index in 0..self.inputs.len() {
                    if matches!(self.inputs[index], InputLink::Asked { .. })
                        && core.inputs[index].source.as_deref() == Some(data_name.as_str())
                    {
                        self.inputs[index] = InputLink::Resolve {
                            at: Instant::now() + UNKNOWN_RETRY,
                        };
                    }
                }
            }
            FromAgent::Error { message } => tracing::warn!("agent: {message}"),
        }
    }

    pub(super) fn on_supervisor(&mut self, core: &mut Core, token: Token, message: FromSupervisor) {
        match message {
            FromSupervisor::Config(config) => {
                for input in core.apply_config(config) {
                    self.relink(core, input);
                }
                self.queue_message(token, &ToSupervisor::Ready);
            }
            FromSupervisor::Start => core.set_active(true),
            FromSupervisor::Stop => core.set_active(false),
            FromSupervisor::Shutdown => core.events.push_back(crate::Event::Shutdown),
            FromSupervisor::Ping => self.queue_message(
                token,
                &ToSupervisor::Pong {
                    stats: Some(core.stats()),
                },
            ),
            FromSupervisor::Error { message } => tracing::error!("supervisor: {message}"),
            FromSupervisor::Health { seq, health } => core.on_health(seq, &health),
            // Kept state is for a process's start: a reconnection of the same process to the
            // config server has its own state already.
            FromSupervisor::Kept { .. } => {}
        }
    }
}
