//! The ArMoR side of a benchmark: an agent and a node hosted in this process.

use std::net::{Ipv4Addr, SocketAddr};
use std::time::Duration;

use anyhow::Context as _;
use armor_module_api::{ModuleSpec, Node, Standalone};

/// The bench's node name: its outputs are `bench.OUTPUT`.
pub const NODE_NAME: &str = "bench";
/// How long modules have to link up before a benchmark gives up.
pub const LINK_TIMEOUT: Duration = Duration::from_secs(20);
/// No single wait of a timed loop lasts longer than this (a dead peer fails the bench).
pub const STALL_TIMEOUT: Duration = Duration::from_secs(10);

/// A fresh agent on a thread of this process, on a free port (one per benchmark, so that no
/// registration outlives the benchmark that made it).
pub fn agent() -> anyhow::Result<SocketAddr> {
    armor_runtime::agent::spawn(SocketAddr::from((Ipv4Addr::LOCALHOST, 0)))
        .context("cannot start an agent")
}

/// Hosts a module named [`NODE_NAME`] in this process, its inputs bound as `binds` says
/// (`input`, `module.output`).
pub fn connect(
    spec: ModuleSpec,
    agent: SocketAddr,
    binds: &[(&str, &str)],
) -> anyhow::Result<Node> {
    Node::connect(
        spec,
        Standalone {
            name: Some(NODE_NAME.to_owned()),
            agent: Some(agent.to_string()),
            binds: binds
                .iter()
                .map(|&(input, source)| (input.to_owned(), source.to_owned()))
                .collect(),
            ..Standalone::default()
        },
    )
    .context("cannot connect the bench's node")
}

/// How a benchmark's links are secured: plain, or with a shared secret (authenticated), and
/// then perhaps encrypted too — as `armor run --secret FILE [--encrypt]` runs them.
pub enum Security {
    Plain,
    Secret {
        /// Holds the secret file for as long as the benchmark runs.
        _dir: tempfile::TempDir,
        file: std::path::PathBuf,
        secret: armor_module_api::auth::Secret,
        encrypt: bool,
    },
}

impl Security {
    /// A secret in a private file (a fixed one: a benchmark guards nothing).
    pub fn with_secret(encrypt: bool) -> anyhow::Result<Security> {
        use std::os::unix::fs::PermissionsExt as _;
        let dir = tempfile::tempdir().context("cannot make a folder for the secret")?;
        let file = dir.path().join("secret");
        std::fs::write(&file, "armor-bench: a secret that guards nothing\n")?;
        std::fs::set_permissions(&file, std::fs::Permissions::from_mode(0o600))?;
        let secret = armor_module_api::auth::Secret::load(&file)?;
        Ok(Security::Secret {
            _dir: dir,
            file,
            secret,
            encrypt,
        })
    }

    /// An agent as [`agent`] starts, holding the secret.
    pub fn agent(&self) -> anyhow::Result<SocketAddr> {
        match self {
            Security::Plain => agent(),
            Security::Secret { secret, .. } => armor_runtime::agent::spawn_with(
                SocketAddr::from((Ipv4Addr::LOCALHOST, 0)),
                Some(secret.clone()),
            )
            .context("cannot start an agent"),
        }
    }

    /// The bench's node as [`connect`] hosts it, proving its key.
    pub fn connect(
        &self,
        spec: ModuleSpec,
        agent: SocketAddr,
        binds: &[(&str, &str)],
    ) -> anyhow::Result<Node> {
        let Security::Secret { file, encrypt, .. } = self else {
            return connect(spec, agent, binds);
        };
        Node::connect(
            spec,
            Standalone {
                name: Some(NODE_NAME.to_owned()),
                agent: Some(agent.to_string()),
                binds: binds
                    .iter()
                    .map(|&(input, source)| (input.to_owned(), source.to_owned()))
                    .collect(),
                secret: Some(file.clone()),
                encrypt: *encrypt,
                ..Standalone::default()
            },
        )
        .context("cannot connect the bench's node")
    }

    /// Gives a module process named `name` its key (as `armor run` does), or none.
    pub fn module_env(
        &self,
        command: &mut std::process::Command,
        name: &str,
    ) -> anyhow::Result<()> {
        use armor_module_api::auth::{ENV_ENCRYPT, ENV_KEY_FD, ENV_SECRET_FILE};
        command
            .env_remove(ENV_KEY_FD)
            .env_remove(ENV_ENCRYPT)
            .env_remove(ENV_SECRET_FILE);
        if let Security::Secret {
            secret, encrypt, ..
        } = self
        {
            armor_runtime::process::hand_over(command, &secret.module_key(name).to_hex())
                .context("cannot hand the module its key")?;
            if *encrypt {
                command.env(ENV_ENCRYPT, "1");
            }
        }
        Ok(())
    }
}
