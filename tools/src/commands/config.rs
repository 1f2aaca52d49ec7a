//! `defrag --config FILE.toml`: top-level defrag options and per-plugin parameter tables
//! (`[scorer.NAME]`, `[solver.NAME]`, `[packer.NAME]`), merged under the command-line flags, and
//! the check of every plugin name and parameter against the registry before any work starts.
//! A plugin is chosen with `solver = "slim"` at the top level, or with `[solver] use = "slim,arap"`
//! when the file also has `[solver.NAME]` tables (TOML allows only one of the two forms).

use std::collections::BTreeMap;
use std::path::Path;

use clap::ValueEnum;
use scanatlas_core::defrag::MergeOptions;
use scanatlas_core::pack::{PackOptions, check_sheet_shape};
use scanatlas_core::pipeline::defrag::DefragConfig;
use scanatlas_core::plugin::{ParamValue, Params, PluginKind, Registry};

use super::UsageError;
use crate::cli::{DefragArgs, TextureFormatArg, parse_sheet_size};

/// The top-level keys a config file may hold (besides the plugin tables).
pub const TOP_LEVEL_KEYS: [&str; 31] = [
    "matching-tolerance",
    "boundary-tolerance",
    "local-distortion",
    "global-distortion",
    "alpha",
    "uv-border-target",
    "time-limit",
    "no-retry",
    "serial",
    "cluster-faces",
    "merge-only",
    "no-untangle",
    "no-clash-separation",
    "split-rigid",
    "speck-area",
    "no-solve-repair",
    "no-one-sided",
    "energy-ration",
    "no-defer",
    "rescue-share",
    "scorer",
    "solver",
    "packer",
    "padding",
    "max-sheet-size",
    "sheet-size",
    "pow2",
    "align",
    "texel-scale",
    "texture-format",
    "jpeg-quality",
];

/// What a config file says.
#[derive(Debug, Default)]
pub struct FileConfig {
    /// Top-level options, by key.
    pub options: BTreeMap<String, toml::Value>,
    /// Parameters per plugin kind and name.
    pub plugins: BTreeMap<(PluginKind, String), Params>,
}

fn usage(msg: impl Into<String>) -> UsageError {
    UsageError(msg.into())
}

fn param_value(where_: &str, v: &toml::Value) -> Result<ParamValue, UsageError> {
    Ok(match v {
        toml::Value::Integer(i) => ParamValue::Int(*i),
        toml::Value::Float(x) => ParamValue::Float(*x),
        toml::Value::Boolean(b) => ParamValue::Bool(*b),
        toml::Value::String(s) => ParamValue::Text(s.clone()),
        _ => return Err(usage(format!("{where_}: expected a number, a boolean or a string"))),
    })
}

impl FileConfig {
    /// Parses the text of a config file (`origin` names it in messages).
    pub fn parse(text: &str, origin: &str) -> Result<Self, UsageError> {
        let table: toml::Table =
            text.parse().map_err(|e: toml::de::Error| usage(format!("{origin}: {e}")))?;
        let mut cfg = Self::default();
        for (key, value) in table {
            let kind = match key.as_str() {
                "scorer" if value.is_table() => Some(PluginKind::Scorer),
                "solver" if value.is_table() => Some(PluginKind::Solver),
                "packer" if value.is_table() => Some(PluginKind::Packer),
                _ => None,
            };
            let Some(kind) = kind else {
                if !TOP_LEVEL_KEYS.contains(&key.as_str()) {
                    return Err(usage(format!(
                        "{origin}: unknown option `{key}`; valid: {}, and the tables [scorer.NAME], [solver.NAME], [packer.NAME]",
                        TOP_LEVEL_KEYS.join(", ")
                    )));
                }
                cfg.options.insert(key, value);
                continue;
            };
            let toml::Value::Table(plugins) = value else { continue };
            for (name, params) in plugins {
                // TOML cannot hold both `solver = "slim"` and a `[solver.slim]` table, so the
                // selection may also be written inside the kind's table: `[solver] use = "slim"`.
                if name == "use" {
                    cfg.options.insert(key.clone(), params);
                    continue;
                }
                let toml::Value::Table(params) = params else {
                    return Err(usage(format!(
                        "{origin}: [{key}.{name}] must be a table of parameters"
                    )));
                };
                let mut out = Params::new();
                for (p, v) in &params {
                    out.insert(p.clone(), param_value(&format!("{origin}: {key}.{name}.{p}"), v)?);
                }
                cfg.plugins.insert((kind, name), out);
            }
        }
        Ok(cfg)
    }

    /// Reads and parses a config file.
    pub fn load(path: &Path) -> Result<Self, UsageError> {
        let text = std::fs::read_to_string(path)
            .map_err(|e| usage(format!("cannot read the config file {}: {e}", path.display())))?;
        Self::parse(&text, &path.display().to_string())
    }

    fn get<T>(
        &self,
        key: &str,
        read: impl Fn(&toml::Value) -> Option<T>,
        what: &str,
    ) -> Result<Option<T>, UsageError> {
        match self.options.get(key) {
            None => Ok(None),
            Some(v) => read(v)
                .map(Some)
                .ok_or_else(|| usage(format!("config option `{key}`: expected {what}"))),
        }
    }

    fn float(&self, key: &str) -> Result<Option<f64>, UsageError> {
        self.get(
            key,
            |v| match v {
                toml::Value::Float(x) => Some(*x),
                toml::Value::Integer(i) => Some(*i as f64),
                _ => None,
            },
            "a number",
        )
    }

    fn text(&self, key: &str) -> Result<Option<String>, UsageError> {
        self.get(key, |v| v.as_str().map(str::to_string), "a string")
    }

    fn flag(&self, key: &str) -> Result<bool, UsageError> {
        Ok(self.get(key, toml::Value::as_bool, "true or false")?.unwrap_or(false))
    }

    fn whole(&self, key: &str, max: i64) -> Result<Option<i64>, UsageError> {
        self.get(
            key,
            |v| v.as_integer().filter(|i| (0..=max).contains(i)),
            &format!("a whole number from 0 to {max}"),
        )
    }

    /// A sheet size option (`W` or `"WxH"`).
    fn sheet_size(&self, key: &str) -> Result<Option<(u32, u32)>, UsageError> {
        let parse_sheet_size =
            |s: &str| parse_sheet_size(s).map_err(|e| format!("config option `{key}`: {e}"));
        match self.options.get(key) {
            None => Ok(None),
            Some(toml::Value::Integer(i)) => {
                Ok(Some(parse_sheet_size(&i.to_string()).map_err(usage)?))
            }
            Some(toml::Value::String(s)) => Ok(Some(parse_sheet_size(s).map_err(usage)?)),
            Some(_) => Err(usage(format!("config option `{key}`: expected W or \"WxH\""))),
        }
    }

    /// The `texture-format` option, by the names `--texture-format` takes.
    fn texture_format(&self) -> Result<Option<TextureFormatArg>, UsageError> {
        let Some(name) = self.text("texture-format")? else { return Ok(None) };
        TextureFormatArg::from_str(&name, true).map(Some).map_err(|_| {
            let valid: Vec<String> = TextureFormatArg::value_variants()
                .iter()
                .filter_map(|v| v.to_possible_value().map(|p| p.get_name().to_string()))
                .collect();
            usage(format!(
                "config option `texture-format`: unknown format {name:?}; valid: {}",
                valid.join(", ")
            ))
        })
    }

    /// The parameters of plugin `name` of `kind` given in the file (empty when none).
    pub fn params(&self, kind: PluginKind, name: &str) -> Params {
        self.plugins.get(&(kind, name.to_string())).cloned().unwrap_or_default()
    }
}

/// The parameters of the solver `name` (a chain or a rescued solver gets each member's table,
/// qualified `member.key`).
fn solver_params(file: &FileConfig, name: &str) -> Params {
    if !name.contains([',', '+']) {
        return file.params(PluginKind::Solver, name);
    }
    let mut out = Params::new();
    for member in name.split([',', '+']).map(str::trim) {
        for (k, v) in file.params(PluginKind::Solver, member) {
            out.insert(format!("{member}.{k}"), v);
        }
    }
    out
}

/// The pipeline configuration from the command line over the config file over the defaults, with
/// every plugin name and parameter (also of tables for plugins this run does not use) checked.
pub fn defrag_config(args: &DefragArgs, registry: &Registry) -> Result<DefragConfig, UsageError> {
    let file = match &args.config {
        Some(path) => FileConfig::load(path)?,
        None => FileConfig::default(),
    };
    for ((kind, name), params) in &file.plugins {
        registry.check(*kind, name, params).map_err(|e| usage(format!("config file: {e}")))?;
    }
    let merge = merge_options(args, &file)?;
    merge.validate().map_err(|e| usage(e.to_string()))?;
    let base = DefragConfig::default();
    let scorer = args.scorer.clone().or(file.text("scorer")?).unwrap_or(base.scorer);
    let solver = args.solver.clone().or(file.text("solver")?).unwrap_or(base.solver);
    let packer = args.packer.clone().or(file.text("packer")?).unwrap_or(base.packer);

    let scorer_params = scorer_params(args, &file, &scorer)?;
    let solver_params = solver_params(&file, &solver);
    let packer_params = file.params(PluginKind::Packer, &packer);
    registry
        .check(PluginKind::Scorer, &scorer, &scorer_params)
        .map_err(|e| usage(e.to_string()))?;
    registry
        .check(PluginKind::Solver, &solver, &solver_params)
        .map_err(|e| usage(e.to_string()))?;
    registry
        .check(PluginKind::Packer, &packer, &packer_params)
        .map_err(|e| usage(e.to_string()))?;

    // A size on the command line replaces both sizes of the file (they exclude each other).
    let (max_sheet_size, sheet_size) = match (args.max_sheet_size, args.sheet_size) {
        (None, None) => (file.sheet_size("max-sheet-size")?, file.sheet_size("sheet-size")?),
        flags => flags,
    };
    let padding = match args.padding {
        Some(p) => p,
        None => file.whole("padding", 4096)?.map_or(PackOptions::default().padding, |p| p as u32),
    };
    let jpeg_quality = match args.jpeg_quality {
        Some(q) => q,
        None => match file.whole("jpeg-quality", 100)? {
            Some(0) => return Err(usage("config option `jpeg-quality`: expected 1 to 100")),
            Some(q) => q as u8,
            None => base.jpeg_quality,
        },
    };
    let texture_format = match args.texture_format {
        Some(f) => Some(f),
        None => file.texture_format()?,
    };
    let align = match args.align {
        Some(a) => a,
        None => file
            .whole("align", i64::from(scanatlas_core::pack::MAX_ALIGN))?
            .map_or(PackOptions::default().align, |a| a as u32),
    };
    let split_rigid_ratio =
        pick(&file, args.split_rigid, "split-rigid", PackOptions::default().split_rigid_ratio)?;
    if !(split_rigid_ratio.is_finite() && split_rigid_ratio >= 0.0) {
        return Err(usage(format!("--split-rigid must be 0 or more, got {split_rigid_ratio}")));
    }
    let speck_area = pick(&file, args.speck_area, "speck-area", PackOptions::default().speck_area)?;
    if !(speck_area.is_finite() && speck_area >= 0.0) {
        return Err(usage(format!(
            "--speck-area must be a finite number, 0 or more, got {speck_area}"
        )));
    }
    let pack = PackOptions {
        padding,
        max_sheet_size,
        sheet_size,
        pow2: args.pow2 || file.flag("pow2")?,
        align,
        texel_scale: pick(
            &file,
            args.texel_scale,
            "texel-scale",
            PackOptions::default().texel_scale,
        )?,
        separate_texel_clashes: !(args.no_clash_separation || file.flag("no-clash-separation")?),
        split_rigid_ratio,
        speck_area,
        ..PackOptions::default()
    };
    check_sheet_shape(&pack).map_err(usage)?;
    Ok(DefragConfig {
        merge,
        scorer,
        scorer_params,
        solver,
        solver_params,
        packer,
        packer_params,
        pack,
        texture_format: texture_format.map(super::defrag::image_format),
        jpeg_quality,
        lossy_webp: texture_format.is_some_and(crate::cli::TextureFormatArg::is_lossy_webp),
        work_dir: args.work_dir.clone(),
        report: args.report.clone(),
        metrics_overlaps: None,
        merge_only: args.merge_only || file.flag("merge-only")?,
        untangle: if args.no_untangle || file.flag("no-untangle")? { None } else { base.untangle },
        ..base
    })
}

/// A number from its flag, else from the config file's `key`, else `default`.
fn pick(file: &FileConfig, flag: Option<f64>, key: &str, default: f64) -> Result<f64, UsageError> {
    Ok(match flag {
        Some(x) => x,
        None => file.float(key)?.unwrap_or(default),
    })
}

/// The merge options from the command line over the config file over the defaults.
fn merge_options(args: &DefragArgs, file: &FileConfig) -> Result<MergeOptions, UsageError> {
    let defaults = MergeOptions::default();
    let serial = args.serial || file.flag("serial")?;
    Ok(MergeOptions {
        local_distortion: pick(
            file,
            args.local_distortion,
            "local-distortion",
            defaults.local_distortion,
        )?,
        global_distortion: pick(
            file,
            args.global_distortion,
            "global-distortion",
            defaults.global_distortion,
        )?,
        alpha: pick(file, args.alpha, "alpha", defaults.alpha)?,
        uv_border_target: pick(
            file,
            args.uv_border_target,
            "uv-border-target",
            defaults.uv_border_target,
        )?,
        time_limit: pick(file, args.time_limit, "time-limit", defaults.time_limit)?,
        no_retry: args.no_retry || file.flag("no-retry")?,
        solve_repair: !(args.no_solve_repair || file.flag("no-solve-repair")?),
        one_sided: !(args.no_one_sided || file.flag("no-one-sided")?),
        energy_ration: pick(file, args.energy_ration, "energy-ration", defaults.energy_ration)?,
        defer: !(args.no_defer || file.flag("no-defer")?),
        rescue_share: pick(file, args.rescue_share, "rescue-share", defaults.rescue_share)?,
        speculate: !serial,
        cluster_faces: if serial {
            0
        } else {
            match args.cluster_faces {
                Some(n) => n,
                None => file
                    .whole("cluster-faces", i64::from(u32::MAX))?
                    .map_or(defaults.cluster_faces, |n| n as u32),
            }
        },
        ..defaults
    })
}

/// The scorer's parameters: its table in the config file, with the m and b filters set by
/// their flags or top-level keys.
fn scorer_params(args: &DefragArgs, file: &FileConfig, scorer: &str) -> Result<Params, UsageError> {
    // The m and b filters are scorer parameters; the flags and the top-level keys set them for
    // whichever scorer runs, over its own table.
    let mut scorer_params = file.params(PluginKind::Scorer, scorer);
    for (flag, key) in [
        (args.matching_tolerance, "matching-tolerance"),
        (args.boundary_tolerance, "boundary-tolerance"),
    ] {
        let value = match flag {
            Some(x) => Some(x),
            None if scorer_params.contains_key(key) => None,
            None => file.float(key)?,
        };
        if let Some(x) = value {
            scorer_params.insert(key.to_string(), ParamValue::Float(x));
        }
    }
    Ok(scorer_params)
}

#[cfg(test)]
mod tests {
    use super::*;
    use clap::Parser;

    fn registry() -> Registry {
        let mut r = Registry::default();
        scanatlas_plugins::register_builtin(&mut r);
        r
    }

    fn args(extra: &[&str]) -> DefragArgs {
        let mut argv = vec!["scanatlas", "defrag", "in.obj", "-o", "out.obj"];
        argv.extend_from_slice(extra);
        match crate::cli::Cli::parse_from(argv).command {
            crate::cli::Command::Defrag(a) => *a,
            _ => unreachable!(),
        }
    }

    fn with_file(text: &str, extra: &[&str]) -> Result<DefragConfig, UsageError> {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("c.toml");
        std::fs::write(&path, text).unwrap();
        let p = path.to_str().unwrap().to_string();
        let mut all = vec!["--config", p.as_str()];
        all.extend_from_slice(extra);
        defrag_config(&args(&all), &registry())
    }

    #[test]
    fn defaults_without_a_file() {
        let cfg = defrag_config(&args(&[]), &registry()).unwrap();
        assert_eq!(cfg.merge, MergeOptions::default());
        assert_eq!((cfg.scorer.as_str(), cfg.solver.as_str()), ("paper", "arap+slim"));
        assert!(cfg.scorer_params.is_empty() && cfg.solver_params.is_empty());
    }

    #[test]
    fn flags_override_the_file_and_tables_reach_their_plugins() {
        let text = r#"
            alpha = 10
            no-retry = true
            matching-tolerance = 3.0
            max-sheet-size = "2048x1024"
            [solver]
            use = "slim,arap"
            [solver.slim]
            max-iterations = 20
            [solver.arap]
            tolerance = 1e-6
            [scorer.paper]
            boundary-tolerance = 0.3
            [packer.skyline]
        "#;
        let cfg = with_file(text, &["--alpha", "2.5"]).unwrap();
        assert_eq!(cfg.merge.alpha, 2.5);
        assert!(cfg.merge.no_retry);
        assert_eq!(cfg.solver, "slim,arap");
        assert_eq!(cfg.solver_params.get("slim.max-iterations"), Some(&ParamValue::Int(20)));
        assert_eq!(cfg.solver_params.get("arap.tolerance"), Some(&ParamValue::Float(1e-6)));
        assert_eq!(cfg.scorer_params.get("matching-tolerance"), Some(&ParamValue::Float(3.0)));
        assert_eq!(cfg.scorer_params.get("boundary-tolerance"), Some(&ParamValue::Float(0.3)));
        assert_eq!(cfg.pack.max_sheet_size, Some((2048, 1024)));
        let cfg = with_file(text, &["--solver", "arap", "--boundary-tolerance", "0.1"]).unwrap();
        assert_eq!(cfg.solver, "arap");
        assert_eq!(cfg.solver_params.get("tolerance"), Some(&ParamValue::Float(1e-6)));
        assert_eq!(cfg.scorer_params.get("boundary-tolerance"), Some(&ParamValue::Float(0.1)));
    }

    #[test]
    fn unknown_names_and_parameters_are_refused_with_the_valid_ones() {
        let err = with_file("[solver.slim]\nmax-iteration = 3\n", &[]).unwrap_err().0;
        assert!(err.contains("max-iteration") && err.contains("max-iterations"), "{err}");
        let err = with_file("[solver.slimm]\n", &[]).unwrap_err().0;
        assert!(err.contains("slimm") && err.contains("arap, slim"), "{err}");
        let err = with_file("alpah = 3\n", &[]).unwrap_err().0;
        assert!(err.contains("alpah") && err.contains("alpha"), "{err}");
        let err = with_file("alpha = \"big\"\n", &[]).unwrap_err().0;
        assert!(err.contains("alpha"), "{err}");
        let err = with_file("alpha = -1\n", &[]).unwrap_err().0;
        assert!(err.contains("alpha"), "{err}");
        let err = with_file("[solver.slim]\ninit = \"tutte\"\n", &[]).unwrap_err().0;
        assert!(err.contains("init"), "{err}");
        let err = defrag_config(&args(&["--solver", "slim,rap"]), &registry()).unwrap_err().0;
        assert!(err.contains("rap") && err.contains("arap, slim"), "{err}");
        let err = defrag_config(&args(&["--scorer", "paperr"]), &registry()).unwrap_err().0;
        assert!(err.contains("no-benefit-cost"), "{err}");
        assert!(with_file("not toml [", &[]).is_err());
        // The plain form works without tables.
        let cfg = with_file("solver = \"slim\"\n", &[]).unwrap();
        assert_eq!(cfg.solver, "slim");
    }
}
