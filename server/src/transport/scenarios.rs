//! The scenarios a server creates envs from: the built-in ones and a folder of the
//! operator's, each by the name its file declares, checked once at start.

use arena_sim::{BUILTIN_SCENARIOS, Scenario};

/// Scenario texts the server can create envs from, by name.
#[derive(Debug, Clone, Default)]
pub struct Scenarios {
    entries: Vec<(String, String, String)>,
}

impl Scenarios {
    /// The built-in scenarios plus every `*.toml` in `dir`, each served under the `name`
    /// its file declares (a name in `dir` replaces a built-in one). A folder that cannot
    /// be read, a file that does not load, or two files of one name are an error that
    /// names the file and what is wrong.
    pub fn load(dir: Option<&std::path::Path>) -> Result<Scenarios, String> {
        let mut entries: Vec<(String, String, String)> = BUILTIN_SCENARIOS
            .iter()
            .map(|(name, file, text)| (name.to_string(), file.to_string(), text.to_string()))
            .collect();
        let Some(dir) = dir else { return Ok(Scenarios { entries }) };
        let listing =
            std::fs::read_dir(dir).map_err(|e| format!("cannot read the scenario folder {}: {e}", dir.display()))?;
        let mut paths: Vec<_> =
            listing.flatten().map(|e| e.path()).filter(|p| p.extension().is_some_and(|e| e == "toml")).collect();
        paths.sort();
        let mut seen: Vec<(String, std::path::PathBuf)> = Vec::new();
        for path in paths {
            let scenario = Scenario::load(&path).map_err(|e| format!("{}: {e}", path.display()))?;
            if let Some((_, other)) = seen.iter().find(|(name, _)| *name == scenario.name) {
                return Err(format!(
                    "{} and {} both declare name = \"{}\"; scenario names must be unique",
                    other.display(),
                    path.display(),
                    scenario.name
                ));
            }
            let text = std::fs::read_to_string(&path).map_err(|e| format!("{}: {e}", path.display()))?;
            let file = path.file_name().map_or_else(String::new, |s| s.to_string_lossy().into_owned());
            entries.retain(|(n, ..)| *n != scenario.name);
            entries.push((scenario.name.clone(), file, text));
            seen.push((scenario.name, path));
        }
        Ok(Scenarios { entries })
    }

    /// Scenario names, sorted.
    pub fn names(&self) -> Vec<String> {
        let mut names: Vec<String> = self.entries.iter().map(|(n, ..)| n.clone()).collect();
        names.sort();
        names
    }

    pub(crate) fn get(&self, name: &str) -> Option<(&str, &str)> {
        self.entries.iter().find(|(n, ..)| n == name).map(|(_, file, text)| (file.as_str(), text.as_str()))
    }
}
