//! `highway_arena._core`: the Rust client (`arena_client::blocking`) seen from Python.
//! It moves wire types into plain Python values — observations as (dtype, shape, bytes)
//! so the Python side builds fresh numpy arrays, spaces as dicts, infos as dicts — and
//! releases the GIL while it waits on the network. While recording, the world's frames
//! that replies carry are kept per env until Python takes them (`take_world`), as columns
//! of (dtype, shape, bytes). The PettingZoo and Gymnasium classes live in the Python
//! package on top (python/highway_arena).

use std::sync::Mutex;

use arena_client::blocking::{Client as BlockingClient, Env as BlockingEnv};
use arena_client::{ClientError, EnvSpecs, OptionValue, ScenarioSource};
use arena_eval as eval;
use arena_eval::budget::{self, Budget, Clock};
use arena_eval::stats::Bootstrap;
use arena_protocol::keys::DEFAULT_PREFIX;
use arena_protocol::session::{ConnectionFlags, DEFAULT_CONNECT_TIMEOUT, DEFAULT_ENDPOINT, DEFAULT_TIMEOUT, Mode};
use arena_protocol::{
    Action, ActionType, BuiltinPolicy, CREATE_OPTIONS, CreateOptions, DecisionExplained, EndReason, Frame, Game, Given,
    Info, InfoValue, MetaAction, Observation, ObservationKind, OptionKind, RenderMode, Space, StepReply, Style, Tensor,
    TensorData, WorldFrame, WorldStart,
};
use pyo3::exceptions::{PyRuntimeError, PyTypeError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::{PyBool, PyBytes, PyDict, PyFloat, PyInt, PyList, PyTuple};

pyo3::create_exception!(
    _core,
    ArenaError,
    PyRuntimeError,
    "An error from highway-arena: args are (code, message); code is the server's error code name, or Timeout, NoServer, ServerGone, Zenoh, Protocol, Forked."
);

fn to_py_err(error: ClientError) -> PyErr {
    let code = match &error {
        ClientError::Server(reply) => format!("{:?}", reply.code),
        ClientError::Timeout { .. } => "Timeout".to_string(),
        ClientError::NoServer { .. } => "NoServer".to_string(),
        ClientError::ServerGone { .. } => "ServerGone".to_string(),
        ClientError::Zenoh(_) => "Zenoh".to_string(),
        ClientError::Protocol(_) => "Protocol".to_string(),
        ClientError::Forked { .. } => "Forked".to_string(),
    };
    let message = match &error {
        ClientError::Server(reply) => reply.message.clone(),
        other => other.to_string(),
    };
    ArenaError::new_err((code, message))
}

fn lock<T>(mutex: &Mutex<T>) -> std::sync::MutexGuard<'_, T> {
    mutex.lock().unwrap_or_else(|poisoned| poisoned.into_inner())
}

/// A connection to the Zenoh network of arena-servers.
#[pyclass(module = "highway_arena._core")]
struct Client {
    inner: BlockingClient,
}

#[pymethods]
impl Client {
    #[new]
    #[pyo3(signature = (connect, prefix = DEFAULT_PREFIX.to_string(), timeout = DEFAULT_TIMEOUT, retries = 2, mode = None, zenoh_config = None))]
    fn new(
        py: Python<'_>,
        connect: Vec<String>,
        prefix: String,
        timeout: f64,
        retries: u32,
        mode: Option<String>,
        zenoh_config: Option<std::path::PathBuf>,
    ) -> PyResult<Client> {
        if !(timeout.is_finite() && timeout > 0.0) {
            return Err(PyValueError::new_err(format!("timeout must be a positive number of seconds, not {timeout}")));
        }
        let mode = match mode.as_deref() {
            None => None,
            Some("peer") => Some(Mode::Peer),
            Some("client") => Some(Mode::Client),
            Some("router") => Some(Mode::Router),
            Some(other) => {
                return Err(PyValueError::new_err(format!("mode must be peer, client or router, not {other:?}")));
            }
        };
        if let Some(path) = zenoh_config.as_ref().filter(|path| !path.is_file()) {
            return Err(PyValueError::new_err(format!("zenoh_config {} is not a file", path.display())));
        }
        let flags =
            ConnectionFlags { mode, connect, prefix, timeout, retries, zenoh_config, ..ConnectionFlags::default() };
        let inner = py.detach(|| BlockingClient::connect(&flags)).map_err(to_py_err)?;
        Ok(Client { inner })
    }

    /// Ids of the servers alive now.
    fn servers(&self, py: Python<'_>) -> PyResult<Vec<String>> {
        py.detach(|| self.inner.servers()).map_err(to_py_err)
    }

    /// Servers for `count` new envs, spread by load (fewest envs per core first; see
    /// `arena_client::placement`).
    fn place(&self, py: Python<'_>, count: usize) -> PyResult<Vec<String>> {
        py.detach(|| self.inner.place(count)).map_err(to_py_err)
    }

    /// The first server found, waiting up to `wait` seconds (default: the timeout).
    #[pyo3(signature = (wait = None))]
    fn pick_server(&self, py: Python<'_>, wait: Option<f64>) -> PyResult<String> {
        let wait = wait.and_then(|w| std::time::Duration::try_from_secs_f64(w).ok());
        py.detach(|| match wait {
            Some(wait) => self.inner.pick_server_within(wait),
            None => self.inner.pick_server(),
        })
        .map_err(to_py_err)
    }

    /// Creates an env: `scenario` names one on the server, or `text` is a scenario
    /// file's TOML (then `scenario` names it in error messages). The keywords are the
    /// create options, `CREATE_OPTIONS` (None leaves one at its default).
    #[pyo3(signature = (server, scenario, text = None, **options))]
    fn create_env(
        &self,
        py: Python<'_>,
        server: String,
        scenario: String,
        text: Option<String>,
        options: Option<&Bound<'_, PyDict>>,
    ) -> PyResult<Env> {
        let options = create_options(options)?;
        let source = match text {
            Some(text) => ScenarioSource::Inline { file_name: scenario, text },
            None => ScenarioSource::Named(scenario),
        };
        let env = py.detach(|| self.inner.create_env(&server, source, options)).map_err(to_py_err)?;
        Ok(Env {
            specs: env.specs().clone(),
            server: env.server().to_string(),
            inner: Mutex::new(Some(env)),
            world: Mutex::default(),
            explained: Mutex::default(),
            names: Mutex::default(),
        })
    }

    /// Steps many envs of this client in one round trip; returns, per env, a step result
    /// tuple or the exception it raised (not raised: the caller decides).
    fn step_batch<'py>(
        &self,
        py: Python<'py>,
        envs: Vec<PyRef<'py, Env>>,
        actions: Vec<Bound<'py, PyDict>>,
    ) -> PyResult<Vec<Py<PyAny>>> {
        if envs.len() != actions.len() {
            return Err(PyValueError::new_err(format!("{} envs but {} action dicts", envs.len(), actions.len())));
        }
        let envs: Vec<&Env> = envs.iter().map(|env| &**env).collect();
        let mut addresses: Vec<usize> = envs.iter().map(|env| std::ptr::from_ref(*env) as usize).collect();
        addresses.sort_unstable();
        if addresses.windows(2).any(|pair| pair[0] == pair[1]) {
            return Err(PyValueError::new_err("the same env appears twice in one batch: step each env once per batch"));
        }
        let actions = actions.iter().map(parse_actions).collect::<PyResult<Vec<_>>>()?;
        let results = py.detach(|| {
            // Locks are taken in address order (two batches sharing envs cannot deadlock)
            // and without the GIL, like every other lock of an env.
            let mut order: Vec<usize> = (0..envs.len()).collect();
            order.sort_unstable_by_key(|&i| std::ptr::from_ref(envs[i]) as usize);
            let mut guards: Vec<Option<std::sync::MutexGuard<'_, Option<BlockingEnv>>>> =
                envs.iter().map(|_| None).collect();
            for i in order {
                guards[i] = Some(lock(&envs[i].inner));
            }
            let mut handles = Vec::with_capacity(guards.len());
            for guard in guards.iter_mut().flatten() {
                handles.push(guard.as_mut()?);
            }
            Some(self.inner.step_batch(&mut handles, actions))
        });
        let results = results.ok_or_else(closed_error)?.map_err(to_py_err)?;
        results
            .into_iter()
            .zip(&envs)
            .map(|(result, env)| match result {
                Ok(mut reply) => {
                    lock(&env.world).frames.append(&mut reply.world);
                    lock(&env.explained).append(&mut reply.explain);
                    step_tuple(py, reply).map(|t| t.into_any().unbind())
                }
                Err(error) => Ok(to_py_err(error).into_value(py).into_any()),
            })
            .collect()
    }

    /// Closes the session; servers then close this client's envs. Idempotent.
    fn close(&self, py: Python<'_>) -> PyResult<()> {
        py.detach(|| self.inner.close()).map_err(to_py_err)
    }
}

/// Whether this process was forked from the one that opened this extension's first
/// connection: then no connection works here (`Client` raises `Forked`), and the Python
/// package connects through a fresh copy of the extension (highway_arena/_fork.py).
#[pyfunction]
fn forked() -> bool {
    arena_client::forked()
}

/// A built-in policy's name read as the server reads it (`BuiltinPolicy`'s `FromStr`):
/// ("gt", style or None for the learner's own, game) or ("idm", None, None); an unknown
/// one is a ValueError listing the forms.
#[pyfunction]
fn builtin_policy(name: &str) -> PyResult<(&'static str, Option<&'static str>, Option<&'static str>)> {
    match name.parse::<BuiltinPolicy>().map_err(PyValueError::new_err)? {
        BuiltinPolicy::Gt { style, game } => Ok(("gt", style.map(Style::name), Some(game.name()))),
        BuiltinPolicy::Idm => Ok(("idm", None, None)),
    }
}

/// The create options given as keywords, each read as `CREATE_OPTIONS` says: a value of
/// the wrong type is a TypeError, one the option refuses a ValueError, each naming the
/// option; None leaves an option at its default.
fn create_options(given: Option<&Bound<'_, PyDict>>) -> PyResult<CreateOptions> {
    let mut options = CreateOptions::default();
    for (key, value) in given.into_iter().flat_map(|given| given.iter()) {
        let name: String = key.extract()?;
        let Some(option) = CREATE_OPTIONS.iter().find(|option| option.name == name) else {
            let names = CREATE_OPTIONS.iter().map(|option| option.name).collect::<Vec<_>>().join(", ");
            return Err(PyTypeError::new_err(format!("unknown create option {name:?}; the options are {names}")));
        };
        if value.is_none() {
            continue;
        }
        let wrong = || -> PyResult<PyErr> {
            Ok(PyTypeError::new_err(format!("{name} takes {}, not {}", option.kind.takes(), value.get_type().name()?)))
        };
        let given = match option.kind {
            OptionKind::Flag => Given::Flag(value.is_truthy()?),
            OptionKind::Count => Given::Count(value.extract().or_else(|_| Err(wrong()?))?),
            OptionKind::Pair => {
                let (a, b) = value.extract().or_else(|_| Err(wrong()?))?;
                Given::Pair(a, b)
            }
            OptionKind::Choice(_) => Given::Name(value.extract().or_else(|_| Err(wrong()?))?),
            OptionKind::Overrides => Given::Overrides(overrides(&value)?),
            OptionKind::Names => Given::Names(value.extract().or_else(|_| Err(wrong()?))?),
        };
        (option.set)(&mut options, given).map_err(|e| PyValueError::new_err(format!("{name}: {e}")))?;
    }
    Ok(options)
}

/// Scenario overrides given as a dict or as (key, value) pairs.
fn overrides(value: &Bound<'_, PyAny>) -> PyResult<Vec<(String, OptionValue)>> {
    let pairs: Vec<(Bound<'_, PyAny>, Bound<'_, PyAny>)> = match value.cast::<PyDict>() {
        Ok(dict) => dict.iter().collect(),
        Err(_) => value.extract().map_err(|_| {
            PyTypeError::new_err("overrides must be a dict of dotted scenario keys to values, or (key, value) pairs")
        })?,
    };
    pairs
        .into_iter()
        .map(|(key, value)| {
            let key: String =
                key.extract().map_err(|_| PyTypeError::new_err("override keys must be dotted scenario keys (str)"))?;
            option_value(&key, &value).map(|value| (key, value))
        })
        .collect()
}

fn closed_error() -> PyErr {
    ArenaError::new_err(("EnvClosed".to_string(), "this env was closed; create a new one".to_string()))
}

fn option_value(key: &str, value: &Bound<'_, PyAny>) -> PyResult<OptionValue> {
    if value.is_instance_of::<pyo3::types::PyBool>() {
        return Ok(OptionValue::Bool(value.extract()?));
    }
    if let Ok(int) = value.extract::<i64>() {
        return Ok(OptionValue::Int(int));
    }
    if let Ok(float) = value.extract::<f64>() {
        return Ok(OptionValue::Float(float));
    }
    if let Ok(text) = value.extract::<String>() {
        return Ok(OptionValue::Str(text));
    }
    Err(PyTypeError::new_err(format!(
        "override {key}: expected bool, int, float or str, got {}",
        value.get_type().name()?
    )))
}

fn parse_actions(actions: &Bound<'_, PyDict>) -> PyResult<Vec<(String, Action)>> {
    let mut parsed = Vec::with_capacity(actions.len());
    for (agent, action) in actions.iter() {
        let agent: String =
            agent.extract().map_err(|_| PyTypeError::new_err("action dict keys must be agent names (str)"))?;
        parsed.push((agent.clone(), parse_action(&agent, &action)?));
    }
    Ok(parsed)
}

/// An int (Python or numpy) is a meta action; a sequence of numbers a continuous one.
/// Only what the wire cannot carry is refused here (`Action::from_code`,
/// `Action::from_values`: the server's words, code InvalidAction); the server checks the
/// rest, and whether the env has the agent.
fn parse_action(agent: &str, action: &Bound<'_, PyAny>) -> PyResult<Action> {
    let refused = |message: String| ArenaError::new_err(("InvalidAction", format!("agent '{agent}': {message}")));
    if let Ok(code) = action.extract::<i64>() {
        return Action::from_code(code).map_err(refused);
    }
    if let Ok(values) = action.extract::<Vec<f32>>() {
        return Action::from_values(&values).map_err(refused);
    }
    Err(PyTypeError::new_err(format!(
        "agent '{agent}': an action is an int (meta) or 2 numbers (continuous), got {}",
        action.get_type().name()?
    )))
}

fn tensor_tuple<'py>(py: Python<'py>, tensor: &Tensor) -> PyResult<Bound<'py, PyTuple>> {
    let (dtype, bytes): (&str, Vec<u8>) = match &tensor.data {
        TensorData::F32(v) => ("float32", v.iter().flat_map(|x| x.to_le_bytes()).collect()),
        TensorData::U8(v) => ("uint8", v.clone()),
        TensorData::I8(v) => ("int8", v.iter().map(|&x| x as u8).collect()),
        TensorData::I64(v) => ("int64", v.iter().flat_map(|x| x.to_le_bytes()).collect()),
    };
    let shape = PyTuple::new(py, tensor.shape.iter().copied())?;
    PyTuple::new(py, [dtype.into_pyobject(py)?.into_any(), shape.into_any(), PyBytes::new(py, &bytes).into_any()])
}

/// ("tensor", (dtype, shape, bytes)) or ("dict", [(key, (dtype, shape, bytes)), ...]).
fn observation_value<'py>(py: Python<'py>, observation: &Observation) -> PyResult<Bound<'py, PyAny>> {
    match observation {
        Observation::Tensor(tensor) => Ok(("tensor", tensor_tuple(py, tensor)?).into_pyobject(py)?.into_any()),
        Observation::Dict(items) => {
            let list = PyList::empty(py);
            for (key, tensor) in items {
                list.append((key.as_str(), tensor_tuple(py, tensor)?))?;
            }
            Ok(("dict", list).into_pyobject(py)?.into_any())
        }
    }
}

fn info_dict<'py>(py: Python<'py>, info: &Info) -> PyResult<Bound<'py, PyDict>> {
    let dict = PyDict::new(py);
    for (key, value) in &info.values {
        match value {
            InfoValue::F64(x) => dict.set_item(key, x)?,
            InfoValue::Bool(x) => dict.set_item(key, x)?,
            InfoValue::I64(x) => dict.set_item(key, x)?,
            InfoValue::F64s(x) => dict.set_item(key, x.clone())?,
        }
    }
    Ok(dict)
}

/// The inverse of `info_dict` for the values a last info carries (lists are left out).
fn info_from_dict(dict: &Bound<'_, PyDict>) -> PyResult<Info> {
    let mut values = Vec::with_capacity(dict.len());
    for (key, value) in dict.iter() {
        let key: String = key.extract()?;
        // bool before int: Python's bool is an int.
        let value = if value.is_instance_of::<PyBool>() {
            InfoValue::Bool(value.extract()?)
        } else if value.is_instance_of::<PyInt>() {
            InfoValue::I64(value.extract()?)
        } else if value.is_instance_of::<PyFloat>() {
            InfoValue::F64(value.extract()?)
        } else {
            continue;
        };
        values.push((key, value));
    }
    Ok(Info { values })
}

/// An evaluation's rows (policy, scenario, seed, agent, the agent's last info) as episodes.
fn episodes_of(rows: Vec<(String, String, u64, String, Bound<'_, PyDict>)>) -> PyResult<Vec<eval::Episode>> {
    let mut episodes = Vec::with_capacity(rows.len());
    for (policy, scenario, seed, agent, info) in rows {
        let info = info_from_dict(&info)?;
        episodes
            .push(eval::Episode::from_info(&policy, &scenario, seed, &agent, &info).map_err(PyValueError::new_err)?);
    }
    Ok(episodes)
}

/// The tables of evaluated episodes, as `arena eval` writes them (`arena_eval`):
/// `rows` are (policy, scenario, seed, agent, the agent's last info); returns (Markdown
/// table, summary CSV, paired differences CSV, episodes CSV, JSON); `reference` is the
/// policy the others are compared with (`None`: the first), `bootstrap` the resamples.
#[pyfunction]
#[pyo3(signature = (rows, reference=None, bootstrap=None))]
fn eval_report(
    rows: Vec<(String, String, u64, String, Bound<'_, PyDict>)>,
    reference: Option<String>,
    bootstrap: Option<usize>,
) -> PyResult<(String, String, String, String, String)> {
    let episodes = episodes_of(rows)?;
    let bootstrap = Bootstrap { reps: bootstrap.unwrap_or(Bootstrap::default().reps), ..Bootstrap::default() };
    let settings = eval::Settings { reference, bootstrap };
    let summaries = eval::summarise(&episodes, &settings).map_err(PyValueError::new_err)?;
    Ok((
        eval::markdown(&summaries),
        eval::csv(&summaries),
        eval::differences_csv(&summaries),
        eval::episodes_csv(&episodes),
        eval::json(&summaries, &episodes),
    ))
}

/// A policy's compute budget as Python gets it: (scenario, policy, clock, agent-steps,
/// p50 µs, p99 µs).
type BudgetRow = (String, String, String, usize, f64, f64);

/// The compute budget of evaluated policies (`arena_eval::budget`): `items` are
/// (scenario, policy, clock 'server' or 'client', decision times in µs per agent and
/// step); returns (Markdown, CSV, one row per item).
#[pyfunction]
fn budget_report(items: Vec<(String, String, String, Vec<f32>)>) -> PyResult<(String, String, Vec<BudgetRow>)> {
    let mut budgets = Vec::with_capacity(items.len());
    for (scenario, policy, clock, micros) in items {
        let clock = match clock.as_str() {
            "server" => Clock::Server,
            "client" => Clock::Client,
            other => return Err(PyValueError::new_err(format!("clock must be 'server' or 'client', not {other:?}"))),
        };
        budgets.push(Budget::new(&scenario, &policy, clock, &micros));
    }
    let rows = budgets
        .iter()
        .map(|b| (b.scenario.clone(), b.policy.clone(), b.clock.name().to_string(), b.steps, b.p50_us, b.p99_us))
        .collect();
    Ok((budget::markdown(&budgets), budget::csv(&budgets), rows))
}

/// The opponents of a cross-play run, in column order: (name, [(override key, value)])
/// (`arena_eval::crossplay::opponents`).
#[pyfunction]
fn crossplay_opponents() -> Vec<(String, Vec<(String, String)>)> {
    eval::crossplay::opponents().into_iter().map(|o| (o.name, o.overrides)).collect()
}

/// A cell of a cross-play matrix as Python gets it: (scenario, figure, policy, opponent,
/// value, low, high, one distinct episode, whether its interval overlaps the best cell's
/// (`crossplay::near_best`)), the numbers `None` where no episode applies.
type CrossplayCell = (String, String, String, String, Option<f64>, Option<f64>, Option<f64>, Option<bool>, bool);

/// The cross-play matrices of evaluated episodes (`rows` as `eval_report` takes them, each
/// policy named `<policy> vs <opponent>`): their Markdown and every cell.
#[pyfunction]
#[pyo3(signature = (rows, scenarios, policies, bootstrap=None))]
fn crossplay_report(
    rows: Vec<(String, String, u64, String, Bound<'_, PyDict>)>,
    scenarios: Vec<String>,
    policies: Vec<String>,
    bootstrap: Option<usize>,
) -> PyResult<(String, Vec<CrossplayCell>)> {
    use eval::crossplay;
    let episodes = episodes_of(rows)?;
    let bootstrap = Bootstrap { reps: bootstrap.unwrap_or(Bootstrap::default().reps), ..Bootstrap::default() };
    let settings = eval::Settings { reference: None, bootstrap };
    let summaries = eval::summarise(&episodes, &settings).map_err(PyValueError::new_err)?;
    let opponents = crossplay::opponents();
    let mut cells = Vec::new();
    for scenario in &scenarios {
        for figure in crossplay::MATRIX_FIGURES {
            let matrix = crossplay::matrix(&summaries, scenario, &policies, figure);
            let near = crossplay::near_best(&matrix, figure);
            let names = policies.iter().flat_map(|p| opponents.iter().map(move |o| (p, o)));
            for (((policy, opponent), cell), near) in names.zip(matrix).zip(near) {
                cells.push((
                    scenario.clone(),
                    figure.to_string(),
                    policy.clone(),
                    opponent.name.clone(),
                    cell.map(|c| c.value),
                    cell.map(|c| c.low),
                    cell.map(|c| c.high),
                    cell.map(|c| c.one_distinct),
                    near,
                ));
            }
        }
    }
    Ok((crossplay::markdown(&summaries, &scenarios, &policies), cells))
}

/// Adds evaluated episodes (`rows` as `eval_report` takes them), played under the given
/// settings, to a league (`league`: the file's text, `None` for a new one); returns the
/// league file's new text and league.md ranked by `rank` (`arena_eval::league`).
#[pyfunction]
#[pyo3(signature = (league, rows, scenarios, seed, episodes, max_cycles=None, rank="return".to_string(), bootstrap=None))]
#[allow(clippy::too_many_arguments)]
fn league_add(
    league: Option<String>,
    rows: Vec<(String, String, u64, String, Bound<'_, PyDict>)>,
    scenarios: Vec<String>,
    seed: u64,
    episodes: u64,
    max_cycles: Option<u32>,
    rank: String,
    bootstrap: Option<usize>,
) -> PyResult<(String, String)> {
    use arena_eval::league::{League, LeagueSettings, league_markdown};
    let parsed = episodes_of(rows)?;
    let run = LeagueSettings { scenarios, seed, episodes, max_cycles };
    let mut league = match league {
        Some(text) => League::from_json(&text).map_err(PyValueError::new_err)?,
        None => League::new(run.clone()),
    };
    league.add(&run, &parsed).map_err(PyValueError::new_err)?;
    let bootstrap = Bootstrap { reps: bootstrap.unwrap_or(Bootstrap::default().reps), ..Bootstrap::default() };
    let summaries = league.summaries(&eval::Settings { reference: None, bootstrap }).map_err(PyValueError::new_err)?;
    let table = league_markdown(&league, &summaries, &rank).map_err(PyValueError::new_err)?;
    Ok((league.to_json(), table))
}

fn space_dict<'py>(py: Python<'py>, space: &Space) -> PyResult<Bound<'py, PyDict>> {
    let dict = PyDict::new(py);
    match space {
        Space::Box { low, high, shape, dtype } => {
            dict.set_item("type", "box")?;
            dict.set_item("low", low.clone())?;
            dict.set_item("high", high.clone())?;
            dict.set_item("shape", PyTuple::new(py, shape.iter().copied())?)?;
            dict.set_item("dtype", dtype.numpy_name())?;
        }
        Space::Discrete { n, start } => {
            dict.set_item("type", "discrete")?;
            dict.set_item("n", n)?;
            dict.set_item("start", start)?;
        }
        Space::Dict(items) => {
            dict.set_item("type", "dict")?;
            let list = PyList::empty(py);
            for (key, inner) in items {
                list.append((key.as_str(), space_dict(py, inner)?))?;
            }
            dict.set_item("spaces", list)?;
        }
    }
    Ok(dict)
}

fn pairs<'py, T>(
    py: Python<'py>,
    items: &[(String, T)],
    mut value: impl FnMut(&T) -> PyResult<Bound<'py, PyAny>>,
) -> PyResult<Bound<'py, PyDict>> {
    let dict = PyDict::new(py);
    for (agent, item) in items {
        dict.set_item(agent, value(item)?)?;
    }
    Ok(dict)
}

/// (observations, rewards, terminations, truncations, infos, agents) of a step: the
/// rows of the reply as PettingZoo's five dicts.
fn step_tuple(py: Python<'_>, reply: StepReply) -> PyResult<Bound<'_, PyTuple>> {
    let (observations, rewards, terminations, truncations, infos) =
        (PyDict::new(py), PyDict::new(py), PyDict::new(py), PyDict::new(py), PyDict::new(py));
    for step in &reply.steps {
        let agent = step.agent.as_str();
        observations.set_item(agent, observation_value(py, &step.observation)?)?;
        rewards.set_item(agent, step.reward)?;
        terminations.set_item(agent, step.terminated)?;
        truncations.set_item(agent, step.truncated)?;
        infos.set_item(agent, info_dict(py, &step.info)?)?;
    }
    let agents = PyList::new(py, &reply.agents)?;
    PyTuple::new(
        py,
        [
            observations.into_any(),
            rewards.into_any(),
            terminations.into_any(),
            truncations.into_any(),
            infos.into_any(),
            agents.into_any(),
        ],
    )
}

/// An env on a server.
#[pyclass(module = "highway_arena._core")]
struct Env {
    /// As the server described the env at creation (read without the lock).
    specs: EnvSpecs,
    /// The id of the server it lives on, for its life.
    server: String,
    /// `None` once closed. Locked only with the GIL released: a thread waiting for the
    /// lock never holds the GIL, and the thread holding it never waits for the GIL.
    inner: Mutex<Option<BlockingEnv>>,
    /// What recording replies brought since Python last took it (`take_world`). Held
    /// only for a moment, never across a wait.
    world: Mutex<PendingWorld>,
    /// The decisions explained since Python last took them (`take_explanations`); held
    /// as `world` is.
    explained: Mutex<Vec<DecisionExplained>>,
    /// The vehicles' names of the last world a reset, restore or recording brought, by
    /// index: what an explanation's indices point to (`explained_dict`).
    names: Mutex<Vec<String>>,
}

/// One column of a vehicle frame, by name.
type FrameColumn<T> = (&'static str, fn(&arena_protocol::VehicleFrame) -> T);
/// `take_world`'s (start, frames).
type WorldDicts<'py> = (Option<Bound<'py, PyDict>>, Option<Bound<'py, PyDict>>);

/// A reset's `WorldStart` and the frames of the steps since.
#[derive(Default)]
struct PendingWorld {
    start: Option<Box<WorldStart>>,
    frames: Vec<WorldFrame>,
}

fn column<'py, T: Copy>(
    py: Python<'py>,
    dtype: &str,
    shape: &[usize],
    values: impl Iterator<Item = T>,
    bytes: impl Fn(T) -> [u8; 8],
) -> PyResult<Bound<'py, PyTuple>> {
    let data: Vec<u8> = values.flat_map(bytes).collect();
    let shape = PyTuple::new(py, shape.iter().copied())?;
    PyTuple::new(py, [dtype.into_pyobject(py)?.into_any(), shape.into_any(), PyBytes::new(py, &data).into_any()])
}

/// Frames as columns: `time` (F,), and per vehicle (F, V) `x`, `y`, `heading`, `s`, `d`,
/// `speed`, `accel` (float64), `lane`, `target_lane`, `end` (int64, an `END_REASONS`
/// code); `collisions` a list of dicts.
fn frames_dict<'py>(py: Python<'py>, frames: &[WorldFrame]) -> PyResult<Bound<'py, PyDict>> {
    let count = frames.first().map_or(0, |f| f.vehicles.len());
    if frames.iter().any(|f| f.vehicles.len() != count) {
        return Err(ArenaError::new_err(("Protocol", "frames of one reply with different numbers of vehicles")));
    }
    let dict = PyDict::new(py);
    let shape = [frames.len(), count];
    dict.set_item("time", column(py, "float64", &shape[..1], frames.iter().map(|f| f.time), f64::to_le_bytes)?)?;
    let all = || frames.iter().flat_map(|f| f.vehicles.iter());
    let floats: [FrameColumn<f64>; 7] = [
        ("x", |v| v.x),
        ("y", |v| v.y),
        ("heading", |v| v.heading),
        ("s", |v| v.s),
        ("d", |v| v.d),
        ("speed", |v| v.speed),
        ("accel", |v| v.accel),
    ];
    for (key, get) in floats {
        dict.set_item(key, column(py, "float64", &shape, all().map(get), f64::to_le_bytes)?)?;
    }
    let ints: [FrameColumn<i64>; 3] =
        [("lane", |v| i64::from(v.lane)), ("target_lane", |v| i64::from(v.target_lane)), ("end", |v| v.end.code())];
    for (key, get) in ints {
        dict.set_item(key, column(py, "int64", &shape, all().map(get), i64::to_le_bytes)?)?;
    }
    let collisions = PyList::empty(py);
    for event in frames.iter().flat_map(|f| f.collisions.iter()) {
        let item = PyDict::new(py);
        item.set_item("time", event.time)?;
        item.set_item("rear", event.rear)?;
        item.set_item("front", event.front)?;
        item.set_item("at_fault", event.at_fault.name())?;
        item.set_item("x", event.x)?;
        item.set_item("y", event.y)?;
        collisions.append(item)?;
    }
    dict.set_item("collisions", collisions)?;
    Ok(dict)
}

/// The road (lanes as (n, 2) float64 polylines), the vehicles and the first frame.
fn start_dict<'py>(py: Python<'py>, start: &WorldStart) -> PyResult<Bound<'py, PyDict>> {
    let line = |points: &[[f64; 2]]| {
        column(py, "float64", &[points.len(), 2], points.iter().flatten().copied(), f64::to_le_bytes)
    };
    let lanes = PyList::empty(py);
    for lane in &start.road.lanes {
        let item = PyDict::new(py);
        item.set_item("centre", line(&lane.centre)?)?;
        item.set_item("left", line(&lane.left)?)?;
        item.set_item("right", line(&lane.right)?)?;
        item.set_item("end", lane.end)?;
        item.set_item("ends_early", lane.ends_early)?;
        item.set_item("speed_limit", lane.speed_limit)?;
        lanes.append(item)?;
    }
    let road = PyDict::new(py);
    road.set_item("length", start.road.length)?;
    road.set_item("lane_width", start.road.lane_width)?;
    road.set_item("lanes", lanes)?;
    let vehicles = PyList::empty(py);
    for vehicle in &start.vehicles {
        let item = PyDict::new(py);
        item.set_item("name", &vehicle.name)?;
        item.set_item("learner", vehicle.learner)?;
        let (driver, game, role) = match vehicle.driver {
            arena_protocol::DriverInfo::Learner => ("learner", None, None),
            arena_protocol::DriverInfo::Idm => ("idm", None, None),
            arena_protocol::DriverInfo::Gt { game, role } => ("gt", Some(game.name()), Some(role.name())),
        };
        item.set_item("driver", driver)?;
        item.set_item("game", game)?;
        item.set_item("role", role)?;
        item.set_item("style", vehicle.style.name())?;
        item.set_item("length", vehicle.length)?;
        item.set_item("width", vehicle.width)?;
        vehicles.append(item)?;
    }
    let dict = PyDict::new(py);
    dict.set_item("road", road)?;
    dict.set_item("vehicles", vehicles)?;
    dict.set_item("frame", frames_dict(py, std::slice::from_ref(&start.frame))?)?;
    Ok(dict)
}

impl Env {
    fn with<T: Send>(
        &self,
        py: Python<'_>,
        f: impl FnOnce(&mut BlockingEnv) -> Result<T, ClientError> + Send,
    ) -> PyResult<T> {
        py.detach(|| lock(&self.inner).as_mut().map(f)).ok_or_else(closed_error)?.map_err(to_py_err)
    }

    /// Keeps the vehicles' names of a world a reply brought (none: the last ones stay).
    fn keep_names(&self, start: Option<&WorldStart>) {
        if let Some(start) = start {
            *lock(&self.names) = start.vehicles.iter().map(|v| v.name.clone()).collect();
        }
    }
}

#[pymethods]
impl Env {
    /// The id of the server it lives on.
    #[getter]
    fn server(&self) -> String {
        self.server.clone()
    }

    /// possible_agents, spaces (as dicts), dt, max_cycles, render_fps.
    fn specs<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let specs = &self.specs;
        let dict = PyDict::new(py);
        dict.set_item("possible_agents", specs.possible_agents.clone())?;
        dict.set_item(
            "observation_spaces",
            pairs(py, &specs.observation_spaces, |s| Ok(space_dict(py, s)?.into_any()))?,
        )?;
        dict.set_item("action_spaces", pairs(py, &specs.action_spaces, |s| Ok(space_dict(py, s)?.into_any()))?)?;
        dict.set_item("state_space", space_dict(py, &specs.state_space)?)?;
        dict.set_item("dt", specs.dt)?;
        dict.set_item("max_cycles", specs.max_cycles)?;
        dict.set_item("render_fps", specs.render_fps)?;
        Ok(dict)
    }

    /// (observations, infos); `overrides` change the scenario for this episode alone
    /// (dotted keys, as at creation).
    #[pyo3(signature = (seed = None, overrides = None))]
    fn reset<'py>(
        &self,
        py: Python<'py>,
        seed: Option<u64>,
        overrides: Option<Bound<'py, PyDict>>,
    ) -> PyResult<Bound<'py, PyTuple>> {
        let mut parsed = Vec::new();
        for (key, value) in overrides.iter().flat_map(|overrides| overrides.iter()) {
            let key: String =
                key.extract().map_err(|_| PyTypeError::new_err("override keys must be dotted scenario keys (str)"))?;
            let value = option_value(&key, &value)?;
            parsed.push((key, value));
        }
        let mut reply = self.with(py, move |env| env.reset(seed, parsed))?;
        self.keep_names(reply.world.as_deref());
        *lock(&self.world) = PendingWorld { start: reply.world.take(), frames: Vec::new() };
        lock(&self.explained).clear();
        let (observations, infos) = (PyDict::new(py), PyDict::new(py));
        for start in &reply.agents {
            observations.set_item(&start.agent, observation_value(py, &start.observation)?)?;
            infos.set_item(&start.agent, info_dict(py, &start.info)?)?;
        }
        PyTuple::new(py, [observations.into_any(), infos.into_any()])
    }

    /// (observations, rewards, terminations, truncations, infos, agents).
    fn step<'py>(&self, py: Python<'py>, actions: Bound<'py, PyDict>) -> PyResult<Bound<'py, PyTuple>> {
        let actions = parse_actions(&actions)?;
        let mut reply = self.with(py, move |env| env.step(actions))?;
        lock(&self.world).frames.append(&mut reply.world);
        lock(&self.explained).append(&mut reply.explain);
        step_tuple(py, reply)
    }

    /// Turns recording on or off on the server; turned on after a reset, returns the
    /// world now (as `take_world`'s start), else None.
    fn record<'py>(&self, py: Python<'py>, on: bool) -> PyResult<Option<Bound<'py, PyDict>>> {
        let start = self.with(py, move |env| env.record(on))?;
        self.keep_names(start.as_ref());
        *lock(&self.world) = PendingWorld::default();
        start.map(|start| start_dict(py, &start)).transpose()
    }

    /// (start, frames) that recording replies brought since the last call: the last
    /// reset's road, vehicles and first frame (or None), and the steps' frames as
    /// columns (or None when there are none).
    fn take_world<'py>(&self, py: Python<'py>) -> PyResult<WorldDicts<'py>> {
        let pending = std::mem::take(&mut *lock(&self.world));
        let start = pending.start.map(|start| start_dict(py, &start)).transpose()?;
        let frames = (!pending.frames.is_empty()).then(|| frames_dict(py, &pending.frames)).transpose()?;
        Ok((start, frames))
    }

    /// The game-theoretic decisions explained since the last call (created with
    /// `explain=True`), in time order: a list of dicts (`explained_dict`).
    fn take_explanations<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyList>> {
        let explained = std::mem::take(&mut *lock(&self.explained));
        let names = lock(&self.names).clone();
        let dicts = explained.iter().map(|e| explained_dict(py, e, &names)).collect::<PyResult<Vec<_>>>()?;
        PyList::new(py, dicts)
    }

    /// ("rgb", height, width, bytes) or ("ansi", text), following the vehicle named
    /// `follow` (else the first learner).
    #[pyo3(signature = (mode, follow=None))]
    fn render<'py>(&self, py: Python<'py>, mode: &str, follow: Option<String>) -> PyResult<Bound<'py, PyTuple>> {
        let mode = match mode {
            "rgb_array" => RenderMode::RgbArray,
            "ansi" => RenderMode::Ansi,
            other => {
                return Err(PyValueError::new_err(format!("render mode must be 'rgb_array' or 'ansi', not {other:?}")));
            }
        };
        match self.with(py, move |env| env.render(mode, follow.as_deref()))? {
            Frame::Rgb { height, width, pixels } => ("rgb", height, width, PyBytes::new(py, &pixels)).into_pyobject(py),
            Frame::Ansi(text) => ("ansi", text).into_pyobject(py),
        }
    }

    /// The server's wall time deciding for each learner its built-in policy drives, per
    /// step, in microseconds (docs/protocol.md, "Statistics"): {agent: [float, ...]}.
    fn statistics<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let statistics = self.with(py, |env| env.statistics())?;
        let dict = PyDict::new(py);
        for (agent, micros) in statistics.decision_micros {
            dict.set_item(agent, micros)?;
        }
        Ok(dict)
    }

    /// The env's whole state as bytes (docs/protocol.md, "Snapshots").
    fn snapshot<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyBytes>> {
        let bytes = self.with(py, |env| env.snapshot())?;
        Ok(PyBytes::new(py, &bytes))
    }

    /// Puts a snapshot's state into the env: (observations, infos) of the agents live in
    /// it, as `reset` gives them.
    fn restore<'py>(&self, py: Python<'py>, snapshot: Vec<u8>) -> PyResult<Bound<'py, PyTuple>> {
        let mut reply = self.with(py, move |env| env.restore(snapshot))?;
        self.keep_names(reply.world.as_deref());
        *lock(&self.world) = PendingWorld { start: reply.world.take(), frames: Vec::new() };
        let (observations, infos) = (PyDict::new(py), PyDict::new(py));
        for start in &reply.agents {
            observations.set_item(&start.agent, observation_value(py, &start.observation)?)?;
            infos.set_item(&start.agent, info_dict(py, &start.info)?)?;
        }
        PyTuple::new(py, [observations.into_any(), infos.into_any()])
    }

    /// The global state, as an observation value.
    fn state<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        let state = self.with(py, |env| env.state())?;
        observation_value(py, &state)
    }

    /// Closes the env on the server. Idempotent, and quiet when the server is gone or
    /// the env already closed there: closing is best effort (a server reclaims the envs
    /// of clients that leave), and raising from `close` helps no caller.
    fn close(&self, py: Python<'_>) -> PyResult<()> {
        py.detach(|| {
            if let Some(mut env) = lock(&self.inner).take() {
                let _ = env.close();
            }
        });
        Ok(())
    }
}

/// A `DecisionExplained` as a dict of the same field names (docs/protocol.md, "The AV
/// explained"): `game` and `role` by name, paths as lists of (t, x, y, speed), each table
/// a dict with its costs as flat row-major lists (NaN: skipped); beside each vehicle
/// index, the vehicle's name (`vehicle_name`, `ec_name`, a table's `adjacent_name`) from
/// `names`, None where it has none.
fn explained_dict<'py>(py: Python<'py>, e: &DecisionExplained, names: &[String]) -> PyResult<Bound<'py, PyDict>> {
    let name = |index: u32| names.get(index as usize).map(String::as_str);
    let dict = PyDict::new(py);
    dict.set_item("time", e.time)?;
    dict.set_item("vehicle", e.vehicle)?;
    dict.set_item("vehicle_name", name(e.vehicle))?;
    dict.set_item("game", e.game.name())?;
    dict.set_item("role", e.role.name())?;
    dict.set_item("ec", e.ec)?;
    dict.set_item("ec_name", name(e.ec))?;
    let tables = PyList::empty(py);
    for t in &e.tables {
        let table = PyDict::new(py);
        table.set_item("side", t.side)?;
        table.set_item("adjacent", t.adjacent)?;
        table.set_item("adjacent_name", t.adjacent.and_then(name))?;
        table.set_item("ec_actions", t.ec_actions.clone())?;
        table.set_item("ac_actions", t.ac_actions.clone())?;
        table.set_item("ec_costs", t.ec_costs.clone())?;
        table.set_item("ac_costs", t.ac_costs.clone())?;
        table.set_item("pruned", t.pruned.clone())?;
        table.set_item("row", t.row)?;
        table.set_item("col", t.col)?;
        table.set_item("exact", t.exact)?;
        table.set_item("cost", t.cost)?;
        tables.append(table)?;
    }
    dict.set_item("tables", tables)?;
    dict.set_item("chosen", e.chosen)?;
    dict.set_item("games_accel", e.games_accel)?;
    dict.set_item("accel", e.accel)?;
    dict.set_item("sigma", e.sigma)?;
    dict.set_item("safety", e.safety)?;
    dict.set_item("fallback", e.fallback)?;
    let points = |path: &[arena_protocol::PathPoint]| path.iter().map(|p| (p.t, p.x, p.y, p.speed)).collect::<Vec<_>>();
    dict.set_item("planned", points(&e.planned))?;
    dict.set_item("predicted", points(&e.predicted))?;
    Ok(dict)
}

#[pymodule]
fn _core(m: &Bound<'_, PyModule>) -> PyResult<()> {
    // The connection defaults, defined once in arena-protocol; the Python package reads them.
    m.add("DEFAULT_CONNECT", DEFAULT_ENDPOINT)?;
    m.add("DEFAULT_PREFIX", DEFAULT_PREFIX)?;
    m.add("DEFAULT_TIMEOUT", DEFAULT_TIMEOUT)?;
    m.add("DEFAULT_CONNECT_TIMEOUT", DEFAULT_CONNECT_TIMEOUT)?;
    m.add("PROTOCOL_VERSION", arena_protocol::PROTOCOL_VERSION)?;
    // The protocol's vocabulary, written once in arena-protocol.
    m.add("END_REASONS", EndReason::ALL.map(EndReason::name).to_vec())?;
    m.add("META_ACTIONS", MetaAction::ALL.map(MetaAction::name).to_vec())?;
    m.add("INFO_KEYS", arena_protocol::info::SCHEMA.map(|(key, _)| key).to_vec())?;
    m.add("ACTION_TYPES", ActionType::ALL.map(ActionType::name).to_vec())?;
    m.add("OBSERVATIONS", ObservationKind::ALL.map(ObservationKind::name).to_vec())?;
    m.add("GAMES", Game::ALL.map(Game::name).to_vec())?;
    m.add("STYLES", Style::ALL.map(Style::name).to_vec())?;
    // The colours of frames and recordings, by name; "gt" by style.
    let palette = PyDict::new(m.py());
    for (name, rgb) in arena_protocol::palette::NAMED {
        palette.set_item(name, (rgb[0], rgb[1], rgb[2]))?;
    }
    let gt = PyDict::new(m.py());
    for style in Style::ALL {
        let [r, g, b] = arena_protocol::palette::gt(style);
        gt.set_item(style.name(), (r, g, b))?;
    }
    palette.set_item("gt", gt)?;
    m.add("PALETTE", palette)?;
    let failed = EndReason::ALL.into_iter().filter(|reason| reason.failed());
    m.add("FAILED_END_REASONS", failed.map(EndReason::name).collect::<Vec<_>>())?;
    // The create options (name, default, what it takes, what it does), declared once in
    // arena-protocol: the Python package builds its keywords and their help from them.
    let options = CREATE_OPTIONS.iter().map(|option| {
        let default = match option.kind {
            OptionKind::Flag => PyBool::new(m.py(), false).to_owned().into_any(),
            _ => m.py().None().into_bound(m.py()),
        };
        (option.name, default, option.kind.takes(), option.doc())
    });
    m.add("CREATE_OPTIONS", PyList::new(m.py(), options.collect::<Vec<_>>())?)?;
    m.add_function(wrap_pyfunction!(forked, m)?)?;
    m.add_class::<Client>()?;
    m.add_class::<Env>()?;
    m.add_function(wrap_pyfunction!(builtin_policy, m)?)?;
    m.add_function(wrap_pyfunction!(budget_report, m)?)?;
    m.add_function(wrap_pyfunction!(eval_report, m)?)?;
    m.add_function(wrap_pyfunction!(league_add, m)?)?;
    m.add_function(wrap_pyfunction!(crossplay_opponents, m)?)?;
    m.add_function(wrap_pyfunction!(crossplay_report, m)?)?;
    m.add("ArenaError", m.py().get_type::<ArenaError>())?;
    Ok(())
}
