//! `Registry`: plugin factories by kind and stable kebab-case name, with typed parameters and their
//! defaults, so unknown names and parameters are refused before any work starts.

use std::collections::BTreeMap;

use super::{LocalSolver, MergeScorer, Packer, RescuedSolver, SolverChain};

/// The kinds of plugins.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash, serde::Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum PluginKind {
    /// A [`MergeScorer`]: ranks the candidate merges.
    Scorer,
    /// A [`LocalSolver`]: re-optimizes the UVs of a merge's patch.
    Solver,
    /// A [`Packer`]: places the charts' footprints on sheets.
    Packer,
}

impl std::fmt::Display for PluginKind {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            Self::Scorer => "scorer",
            Self::Solver => "solver",
            Self::Packer => "packer",
        })
    }
}

/// A parameter value.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
#[serde(untagged)]
pub enum ParamValue {
    /// A real number (a tolerance, a weight).
    Float(f64),
    /// A whole number (a count, a seed).
    Int(i64),
    /// A switch.
    Bool(bool),
    /// A word (a mode, such as `slim`'s `init`).
    Text(String),
}

/// A declared parameter of a plugin.
#[derive(Clone, Debug, serde::Serialize)]
pub struct ParamInfo {
    /// The kebab-case key in config files and `member.key` chains.
    pub name: &'static str,
    /// The value used when none is given; its variant is the parameter's type.
    pub default: ParamValue,
    /// One line for `scanatlas plugins`.
    pub help: &'static str,
}

/// The description of a plugin shown by `scanatlas plugins`.
#[derive(Clone, Debug, serde::Serialize)]
pub struct PluginInfo {
    /// Which trait the plugin implements.
    pub kind: PluginKind,
    /// The stable kebab-case name users select it by (`--solver slim`).
    pub name: &'static str,
    /// One line saying what it does.
    pub summary: &'static str,
    /// Every parameter it accepts; any other is refused before work starts.
    pub params: Vec<ParamInfo>,
}

/// Parameter values given by the user (config file or command line), by name.
pub type Params = BTreeMap<String, ParamValue>;

/// Errors of plugin lookup and construction.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum PluginError {
    /// No plugin of this kind has this name.
    #[error("unknown {kind} `{name}`; available: {available}")]
    UnknownName {
        /// The kind looked in.
        kind: PluginKind,
        /// The name asked for.
        name: String,
        /// The registered names of that kind, comma-separated.
        available: String,
    },
    /// The plugin does not declare this parameter.
    #[error("{kind} `{name}` has no parameter `{param}`; its parameters: {available}")]
    UnknownParam {
        /// The plugin's kind.
        kind: PluginKind,
        /// The plugin's name.
        name: String,
        /// The parameter given.
        param: String,
        /// The parameters it declares, comma-separated (`none` when it has none).
        available: String,
    },
    /// The parameter's value has the wrong type or lies outside its range.
    #[error("{kind} `{name}`: parameter `{param}`: {msg}")]
    BadParam {
        /// The plugin's kind.
        kind: PluginKind,
        /// The plugin's name.
        name: String,
        /// The parameter.
        param: String,
        /// What is wrong with the value.
        msg: String,
    },
    /// A plugin of this kind is already registered under this name.
    #[error("a {kind} named `{name}` is already registered")]
    Duplicate {
        /// The plugin's kind.
        kind: PluginKind,
        /// The name taken.
        name: String,
    },
}

type ScorerFactory =
    Box<dyn Fn(&Params) -> Result<Box<dyn MergeScorer>, PluginError> + Send + Sync>;
type SolverFactory =
    Box<dyn Fn(&Params) -> Result<Box<dyn LocalSolver>, PluginError> + Send + Sync>;
type PackerFactory = Box<dyn Fn(&Params) -> Result<Box<dyn Packer>, PluginError> + Send + Sync>;

struct Entry<F> {
    info: PluginInfo,
    factory: F,
}

/// Maps plugin names to factories.
#[derive(Default)]
pub struct Registry {
    scorers: BTreeMap<&'static str, Entry<ScorerFactory>>,
    solvers: BTreeMap<&'static str, Entry<SolverFactory>>,
    packers: BTreeMap<&'static str, Entry<PackerFactory>>,
}

impl std::fmt::Debug for Registry {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Registry")
            .field("scorers", &self.scorers.keys().collect::<Vec<_>>())
            .field("solvers", &self.solvers.keys().collect::<Vec<_>>())
            .field("packers", &self.packers.keys().collect::<Vec<_>>())
            .finish()
    }
}

fn insert<F>(
    map: &mut BTreeMap<&'static str, Entry<F>>,
    info: PluginInfo,
    factory: F,
) -> Result<(), PluginError> {
    if map.contains_key(info.name) {
        return Err(PluginError::Duplicate { kind: info.kind, name: info.name.to_string() });
    }
    map.insert(info.name, Entry { info, factory });
    Ok(())
}

fn lookup<'a, F>(
    map: &'a BTreeMap<&'static str, Entry<F>>,
    kind: PluginKind,
    name: &str,
    params: &Params,
) -> Result<&'a Entry<F>, PluginError> {
    let entry = map.get(name).ok_or_else(|| PluginError::UnknownName {
        kind,
        name: name.to_string(),
        available: map.keys().copied().collect::<Vec<_>>().join(", "),
    })?;
    for key in params.keys() {
        if !entry.info.params.iter().any(|p| p.name == key) {
            let names: Vec<&str> = entry.info.params.iter().map(|p| p.name).collect();
            return Err(PluginError::UnknownParam {
                kind,
                name: name.to_string(),
                param: key.clone(),
                available: if names.is_empty() { "none".into() } else { names.join(", ") },
            });
        }
    }
    Ok(entry)
}

impl Registry {
    /// Registers a scorer under `info.name`; `factory` builds it from checked parameters.
    /// Refuses a name already taken by another scorer.
    pub fn register_scorer(
        &mut self,
        info: PluginInfo,
        factory: impl Fn(&Params) -> Result<Box<dyn MergeScorer>, PluginError> + Send + Sync + 'static,
    ) -> Result<(), PluginError> {
        insert(&mut self.scorers, info, Box::new(factory))
    }

    /// Registers a solver under `info.name`; `factory` builds one instance per worker from
    /// checked parameters. Refuses a name already taken by another solver.
    pub fn register_solver(
        &mut self,
        info: PluginInfo,
        factory: impl Fn(&Params) -> Result<Box<dyn LocalSolver>, PluginError> + Send + Sync + 'static,
    ) -> Result<(), PluginError> {
        insert(&mut self.solvers, info, Box::new(factory))
    }

    /// Registers a packer under `info.name`; `factory` builds it from checked parameters.
    /// Refuses a name already taken by another packer.
    pub fn register_packer(
        &mut self,
        info: PluginInfo,
        factory: impl Fn(&Params) -> Result<Box<dyn Packer>, PluginError> + Send + Sync + 'static,
    ) -> Result<(), PluginError> {
        insert(&mut self.packers, info, Box::new(factory))
    }

    /// Builds the scorer `name`, refusing unknown names and parameters.
    pub fn scorer(&self, name: &str, params: &Params) -> Result<Box<dyn MergeScorer>, PluginError> {
        (lookup(&self.scorers, PluginKind::Scorer, name, params)?.factory)(params)
    }

    /// Builds the solver `name`, refusing unknown names and parameters.
    ///
    /// `name` may be a fallback chain `a,b,...` (see [`SolverChain`]), and it may be
    /// `first+rescue` (see [`RescuedSolver`]), each side a solver or a chain. Every member gets
    /// the parameters written `member.param`, and a plain `param` goes to every member that
    /// declares it (it is unknown when none does). A lone solver takes its parameters plain.
    pub fn solver(&self, name: &str, params: &Params) -> Result<Box<dyn LocalSolver>, PluginError> {
        if !name.contains([',', '+']) {
            return (lookup(&self.solvers, PluginKind::Solver, name, params)?.factory)(params);
        }
        let (first, rescue) = match name.split_once('+') {
            Some((first, rescue)) => (first, Some(rescue)),
            None => (name, None),
        };
        let sides: Vec<Vec<&str>> = std::iter::once(first)
            .chain(rescue)
            .map(|side| side.split(',').map(str::trim).collect())
            .collect();
        let members: Vec<&str> = sides.iter().flatten().copied().collect();
        let mut tables = self.route_solver_params(name, &members, params)?.into_iter();
        let mut built = Vec::with_capacity(sides.len());
        for side in &sides {
            let mut solvers = Vec::with_capacity(side.len());
            for &member in side {
                let own = tables.next().unwrap_or_default();
                let entry = lookup(&self.solvers, PluginKind::Solver, member, &own)?;
                solvers.push((entry.factory)(&own)?);
            }
            built.push(match solvers.len() {
                1 => solvers.pop().expect("one solver"),
                _ => Box::new(SolverChain::new(solvers)) as Box<dyn LocalSolver>,
            });
        }
        let rescue = if built.len() == 2 { built.pop() } else { None };
        let first = built.pop().expect("the first side");
        Ok(match rescue {
            Some(rescue) => Box::new(RescuedSolver::new(first, rescue)),
            None => first,
        })
    }

    /// The parameter table of each member of the composite solver `name`: `member.param` goes
    /// to every occurrence of that member, a plain `param` to every member declaring it. A key
    /// that reaches no member is an error listing what the members accept.
    fn route_solver_params(
        &self,
        name: &str,
        members: &[&str],
        params: &Params,
    ) -> Result<Vec<Params>, PluginError> {
        let mut tables = Vec::with_capacity(members.len());
        let mut used = vec![false; params.len()];
        for &member in members {
            let entry = lookup(&self.solvers, PluginKind::Solver, member, &Params::new())?;
            let mut own = Params::new();
            for (i, (key, value)) in params.iter().enumerate() {
                let param = match key.split_once('.') {
                    Some((owner, param)) if owner == member => param,
                    Some(_) => continue,
                    None if entry.info.params.iter().any(|p| p.name == key) => key.as_str(),
                    None => continue,
                };
                own.insert(param.to_string(), value.clone());
                used[i] = true;
            }
            tables.push(own);
        }
        if let Some(i) = used.iter().position(|u| !u) {
            let mut available: Vec<String> = Vec::new();
            for (k, &member) in members.iter().enumerate() {
                if let Some(e) = self.solvers.get(member)
                    && !members[..k].contains(&member)
                {
                    available.extend(e.info.params.iter().map(|p| format!("{member}.{}", p.name)));
                }
            }
            return Err(PluginError::UnknownParam {
                kind: PluginKind::Solver,
                name: name.to_string(),
                param: params.keys().nth(i).cloned().unwrap_or_default(),
                available: available.join(", "),
            });
        }
        Ok(tables)
    }

    /// Builds the packer `name`, refusing unknown names and parameters.
    pub fn packer(&self, name: &str, params: &Params) -> Result<Box<dyn Packer>, PluginError> {
        (lookup(&self.packers, PluginKind::Packer, name, params)?.factory)(params)
    }

    /// The description of the plugin `name` of `kind`, if registered.
    pub fn info(&self, kind: PluginKind, name: &str) -> Option<&PluginInfo> {
        match kind {
            PluginKind::Scorer => self.scorers.get(name).map(|e| &e.info),
            PluginKind::Solver => self.solvers.get(name).map(|e| &e.info),
            PluginKind::Packer => self.packers.get(name).map(|e| &e.info),
        }
    }

    /// The registered names of `kind`, sorted.
    pub fn names(&self, kind: PluginKind) -> Vec<&'static str> {
        match kind {
            PluginKind::Scorer => self.scorers.keys().copied().collect(),
            PluginKind::Solver => self.solvers.keys().copied().collect(),
            PluginKind::Packer => self.packers.keys().copied().collect(),
        }
    }

    /// Checks that `name` is a registered plugin of `kind` (a solver may be a chain) and that it
    /// accepts `params`, by building it (factories are cheap and have no side effects), so a
    /// configuration of a plugin that is not used in a run is still checked before any work.
    pub fn check(&self, kind: PluginKind, name: &str, params: &Params) -> Result<(), PluginError> {
        match kind {
            PluginKind::Scorer => self.scorer(name, params).map(drop),
            PluginKind::Solver => self.solver(name, params).map(drop),
            PluginKind::Packer => self.packer(name, params).map(drop),
        }
    }

    /// Every registered plugin, by kind then name.
    pub fn infos(&self) -> Vec<&PluginInfo> {
        self.scorers
            .values()
            .map(|e| &e.info)
            .chain(self.solvers.values().map(|e| &e.info))
            .chain(self.packers.values().map(|e| &e.info))
            .collect()
    }
}

/// Reads a whole-number parameter within `range`, falling back to the declared default.
pub fn get_u64(
    params: &Params,
    info: &PluginInfo,
    key: &str,
    range: std::ops::RangeInclusive<u64>,
) -> Result<u64, PluginError> {
    let x = get_f64(params, info, key)?;
    if x.fract() != 0.0 || x < *range.start() as f64 || x > *range.end() as f64 {
        return Err(PluginError::BadParam {
            kind: info.kind,
            name: info.name.to_string(),
            param: key.to_string(),
            msg: format!("expected a whole number from {} to {}", range.start(), range.end()),
        });
    }
    Ok(x as u64)
}

/// Reads a boolean parameter, falling back to the declared default.
pub fn get_bool(params: &Params, info: &PluginInfo, key: &str) -> Result<bool, PluginError> {
    let value =
        params.get(key).or_else(|| info.params.iter().find(|p| p.name == key).map(|p| &p.default));
    match value {
        Some(ParamValue::Bool(b)) => Ok(*b),
        _ => Err(PluginError::BadParam {
            kind: info.kind,
            name: info.name.to_string(),
            param: key.to_string(),
            msg: "expected true or false".to_string(),
        }),
    }
}

/// Reads a float parameter, falling back to the declared default.
pub fn get_f64(params: &Params, info: &PluginInfo, key: &str) -> Result<f64, PluginError> {
    let bad = |msg: &str| PluginError::BadParam {
        kind: info.kind,
        name: info.name.to_string(),
        param: key.to_string(),
        msg: msg.to_string(),
    };
    let value = params
        .get(key)
        .or_else(|| info.params.iter().find(|p| p.name == key).map(|p| &p.default))
        .ok_or_else(|| bad("not declared"))?;
    match value {
        ParamValue::Float(x) if x.is_finite() => Ok(*x),
        ParamValue::Int(i) => Ok(*i as f64),
        _ => Err(bad("expected a finite number")),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::plugin::{PackItem, PackOutput, PackerError};

    struct Nothing;

    impl Packer for Nothing {
        fn pack(&self, _: &[PackItem], _: (u32, u32)) -> Result<PackOutput, PackerError> {
            Ok(PackOutput::default())
        }
    }

    fn info(name: &'static str) -> PluginInfo {
        PluginInfo {
            kind: PluginKind::Packer,
            name,
            summary: "test",
            params: vec![ParamInfo { name: "seed", default: ParamValue::Int(0), help: "" }],
        }
    }

    #[test]
    fn packers_follow_the_registry_rules() {
        let mut r = Registry::default();
        r.register_packer(info("nothing"), |_| Ok(Box::new(Nothing))).unwrap();
        assert!(matches!(
            r.register_packer(info("nothing"), |_| Ok(Box::new(Nothing))),
            Err(PluginError::Duplicate { kind: PluginKind::Packer, .. })
        ));
        assert!(r.packer("nothing", &Params::new()).is_ok());
        match r.packer("other", &Params::new()) {
            Err(PluginError::UnknownName { available, .. }) => assert_eq!(available, "nothing"),
            other => panic!("{:?}", other.err()),
        }
        let mut p = Params::new();
        p.insert("sed".into(), ParamValue::Int(1));
        assert!(matches!(r.packer("nothing", &p), Err(PluginError::UnknownParam { .. })));
        assert_eq!(r.infos().iter().filter(|i| i.kind == PluginKind::Packer).count(), 1);
        let i = info("nothing");
        assert_eq!(get_u64(&Params::new(), &i, "seed", 0..=10), Ok(0));
        p.insert("seed".into(), ParamValue::Float(2.5));
        assert!(get_u64(&p, &i, "seed", 0..=10).is_err());
    }

    struct Still;

    impl LocalSolver for Still {
        fn solve(
            &mut self,
            p: &mut crate::plugin::LocalProblem,
        ) -> Result<crate::plugin::SolveReport, crate::plugin::SolveError> {
            p.validate()?;
            Ok(crate::plugin::SolveReport::default())
        }
    }

    fn solver_info(name: &'static str, params: Vec<ParamInfo>) -> PluginInfo {
        PluginInfo { kind: PluginKind::Solver, name, summary: "test", params }
    }

    #[test]
    fn solver_chains_take_qualified_parameters() {
        let mut r = Registry::default();
        let k = ParamInfo { name: "k", default: ParamValue::Int(1), help: "" };
        r.register_solver(solver_info("a", vec![k]), |_| Ok(Box::new(Still))).unwrap();
        r.register_solver(solver_info("b", vec![]), |_| Ok(Box::new(Still))).unwrap();
        assert!(matches!(
            r.register_solver(solver_info("b", vec![]), |_| Ok(Box::new(Still))),
            Err(PluginError::Duplicate { kind: PluginKind::Solver, .. })
        ));
        assert!(r.solver("a,b", &Params::new()).is_ok());
        assert!(r.solver(" b , a ", &Params::new()).is_ok());
        match r.solver("a,c", &Params::new()) {
            Err(PluginError::UnknownName { name, available, .. }) => {
                assert_eq!((name.as_str(), available.as_str()), ("c", "a, b"));
            }
            other => panic!("{:?}", other.err()),
        }
        assert!(r.solver("a,", &Params::new()).is_err());
        let with = |key: &str| {
            let mut p = Params::new();
            p.insert(key.into(), ParamValue::Int(2));
            p
        };
        assert!(r.solver("a,b", &with("a.k")).is_ok());
        assert!(r.solver("a,b", &with("k")).is_ok());
        match r.solver("a,b", &with("b.k")) {
            Err(PluginError::UnknownParam { name, param, available, .. }) => {
                assert_eq!((name.as_str(), param.as_str(), available.as_str()), ("b", "k", "none"));
            }
            other => panic!("{:?}", other.err()),
        }
        match r.solver("a,b", &with("z")) {
            Err(PluginError::UnknownParam { param, available, .. }) => {
                assert_eq!((param.as_str(), available.as_str()), ("z", "a.k"));
            }
            other => panic!("{:?}", other.err()),
        }
        assert!(r.solver("a,b", &with("c.k")).is_err());
        assert!(r.check(PluginKind::Solver, "a,b", &with("a.k")).is_ok());
        assert!(r.check(PluginKind::Packer, "a", &Params::new()).is_err());
        assert_eq!(r.names(PluginKind::Solver), vec!["a", "b"]);
        assert_eq!(r.info(PluginKind::Solver, "a").map(|i| i.params.len()), Some(1));

        // A rescued solver: each side takes its members' parameters, and one nobody takes fails.
        assert!(r.solver("a+b", &Params::new()).is_ok());
        assert!(r.solver("a+b", &with("a.k")).is_ok());
        assert!(r.solver("b+a", &with("k")).is_ok());
        assert!(r.solver("a,b+b", &with("a.k")).is_ok());
        assert!(r.solver("a+a", &with("a.k")).is_ok());
        assert!(matches!(r.solver("a+b+b", &Params::new()), Err(PluginError::UnknownName { .. })));
        assert!(matches!(r.solver("b+b", &with("k")), Err(PluginError::UnknownParam { .. })));
        assert!(matches!(r.solver("a+b", &with("b.k")), Err(PluginError::UnknownParam { .. })));
        assert!(matches!(r.solver("a+c", &Params::new()), Err(PluginError::UnknownName { .. })));
    }
}
