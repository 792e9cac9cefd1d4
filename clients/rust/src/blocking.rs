//! A blocking face on `Client` for callers without an async runtime (the Python
//! extension, the CLI). It owns a small tokio multi-thread runtime, as Zenoh requires.
//! In a child forked from the process that connected, every call fails at once
//! (`ClientError::Forked`, see `fork`) instead of waiting for ever.

use std::sync::Arc;

use std::time::Duration;

use arena_protocol::session::ConnectionFlags;

use crate::{
    Action, ClientError, CreateOptions, EnvSpecs, EnvStatistics, Frame, Observation, OptionValue, RenderMode,
    ResetReply, Result, ScenarioSource, ServerInfo, StepReply,
};

/// A blocking client. Cheap to clone.
#[derive(Clone, Debug)]
pub struct Client {
    runtime: Arc<tokio::runtime::Runtime>,
    inner: crate::Client,
}

impl Client {
    /// Connects as `flags` say (see `crate::Client::connect`).
    pub fn connect(flags: &ConnectionFlags) -> Result<Client> {
        let runtime = tokio::runtime::Builder::new_multi_thread()
            .worker_threads(2)
            .enable_all()
            .build()
            .map_err(|e| ClientError::Zenoh(format!("cannot start a tokio runtime: {e}")))?;
        let inner = runtime.block_on(crate::Client::connect(flags))?;
        Ok(Client { runtime: Arc::new(runtime), inner })
    }

    /// The async client underneath.
    pub fn inner(&self) -> &crate::Client {
        &self.inner
    }

    /// Runs a future of this client's on its runtime.
    pub fn block_on<F: std::future::Future>(&self, future: F) -> F::Output {
        self.runtime.block_on(future)
    }

    /// Runs a call on its runtime, unless this process is a forked child (`fork`), where
    /// the runtime's threads and Zenoh's do not exist.
    fn run<T>(&self, call: impl std::future::Future<Output = Result<T>>) -> Result<T> {
        crate::fork::check()?;
        self.runtime.block_on(call)
    }

    /// See `crate::Client::servers`.
    pub fn servers(&self) -> Result<Vec<String>> {
        self.run(self.inner.servers())
    }

    /// See `crate::Client::pick_server`.
    pub fn pick_server(&self) -> Result<String> {
        self.run(self.inner.pick_server())
    }

    /// See `crate::Client::pick_server_within`.
    pub fn pick_server_within(&self, wait: Duration) -> Result<String> {
        self.run(self.inner.pick_server_within(wait))
    }

    /// See `crate::Client::server_info`.
    pub fn server_info(&self, server: &str) -> Result<ServerInfo> {
        self.run(self.inner.server_info(server))
    }

    /// See `crate::Client::place`.
    pub fn place(&self, count: usize) -> Result<Vec<String>> {
        self.run(self.inner.place(count))
    }

    /// See `crate::Client::server_infos`.
    pub fn server_infos(&self) -> Result<Vec<ServerInfo>> {
        self.run(self.inner.server_infos())
    }

    /// See `crate::Client::create_env`.
    pub fn create_env(&self, server: &str, scenario: ScenarioSource, options: CreateOptions) -> Result<Env> {
        let env = self.run(self.inner.create_env(server, scenario, options))?;
        Ok(Env { client: self.clone(), env })
    }

    /// See `crate::Client::step_batch`.
    pub fn step_batch(
        &self,
        envs: &mut [&mut Env],
        actions: Vec<Vec<(String, Action)>>,
    ) -> Result<Vec<Result<StepReply>>> {
        let mut remotes: Vec<&mut crate::RemoteEnv> = envs.iter_mut().map(|e| &mut e.env).collect();
        self.run(self.inner.step_batch(&mut remotes, actions))
    }

    /// See `crate::Client::close`. In a forked child there is nothing to close: the
    /// session is the parent's.
    pub fn close(&self) -> Result<()> {
        if crate::fork::forked() {
            return Ok(());
        }
        self.run(self.inner.close())
    }
}

impl Drop for Client {
    /// In a forked child the runtime and the session are leaked: dropping either waits on
    /// threads that only the parent has.
    fn drop(&mut self) {
        if crate::fork::forked() {
            std::mem::forget(Arc::clone(&self.runtime));
            std::mem::forget(self.inner.clone());
        }
    }
}

/// A blocking handle on a remote env.
#[derive(Debug)]
pub struct Env {
    client: Client,
    env: crate::RemoteEnv,
}

impl Env {
    /// See `crate::RemoteEnv::server`.
    pub fn server(&self) -> &str {
        self.env.server()
    }

    /// See `crate::RemoteEnv::specs`.
    pub fn specs(&self) -> &EnvSpecs {
        self.env.specs()
    }

    /// See `crate::RemoteEnv::reset`.
    pub fn reset(&mut self, seed: Option<u64>, overrides: Vec<(String, OptionValue)>) -> Result<ResetReply> {
        self.client.run(self.env.reset(seed, overrides))
    }

    /// See `crate::RemoteEnv::step`.
    pub fn step(&mut self, actions: Vec<(String, Action)>) -> Result<StepReply> {
        self.client.run(self.env.step(actions))
    }

    /// See `crate::RemoteEnv::render`.
    pub fn render(&self, mode: RenderMode, follow: Option<&str>) -> Result<Frame> {
        self.client.run(self.env.render(mode, follow))
    }

    /// See `crate::RemoteEnv::statistics`.
    pub fn statistics(&self) -> Result<EnvStatistics> {
        self.client.run(self.env.statistics())
    }

    /// See `crate::RemoteEnv::state`.
    pub fn state(&self) -> Result<Observation> {
        self.client.run(self.env.state())
    }

    /// See `crate::RemoteEnv::record`.
    pub fn record(&self, on: bool) -> Result<Option<arena_protocol::WorldStart>> {
        self.client.run(self.env.record(on))
    }

    /// See `crate::RemoteEnv::snapshot`.
    pub fn snapshot(&self) -> Result<Vec<u8>> {
        self.client.run(self.env.snapshot())
    }

    /// See `crate::RemoteEnv::restore`.
    pub fn restore(&mut self, snapshot: Vec<u8>) -> Result<ResetReply> {
        self.client.run(self.env.restore(snapshot))
    }

    /// See `crate::RemoteEnv::close`.
    pub fn close(&mut self) -> Result<()> {
        self.client.run(self.env.close())
    }
}
