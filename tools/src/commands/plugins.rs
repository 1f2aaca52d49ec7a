//! `scanatlas plugins`: every registered plugin with its kind, name, one-line summary and
//! parameters with their defaults (as text, or as JSON with `--json`).

use std::fmt::Write;

use anyhow::Result;
use scanatlas_core::plugin::ParamValue;

use crate::cli::PluginsArgs;

fn show(v: &ParamValue) -> String {
    match v {
        ParamValue::Float(x) => format!("{x}"),
        ParamValue::Int(i) => format!("{i}"),
        ParamValue::Bool(b) => format!("{b}"),
        ParamValue::Text(t) => format!("{t:?}"),
    }
}

pub fn run(args: &PluginsArgs) -> Result<()> {
    let registry = super::defrag::builtin_registry();
    let infos = registry.infos();
    if args.json {
        return super::print_out(serde_json::to_string_pretty(&infos)? + "\n");
    }
    let mut text = String::new();
    for info in infos {
        writeln!(text, "{} {}: {}", info.kind, info.name, info.summary)?;
        for p in &info.params {
            writeln!(text, "    {} = {}    {}", p.name, show(&p.default), p.help)?;
        }
    }
    writeln!(text)?;
    writeln!(
        text,
        "Parameters go in a config file (`defrag --config FILE.toml`) as `[KIND.NAME]` tables,"
    )?;
    writeln!(
        text,
        "e.g. `[solver.slim]` then `max-iterations = 20`; `--solver slim,arap` is a fallback chain,"
    )?;
    writeln!(
        text,
        "and `--solver arap+slim` (the default) solves again with slim the refused merges of long seams."
    )?;
    super::print_out(text)
}
