//! `scanatlas plugins`: every registered plugin with its kind, name, one-line summary and
//! parameters with their defaults (as text, or as JSON with `--json`).

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
        println!("{}", serde_json::to_string_pretty(&infos)?);
        return Ok(());
    }
    for info in infos {
        println!("{} {}: {}", info.kind, info.name, info.summary);
        for p in &info.params {
            println!("    {} = {}    {}", p.name, show(&p.default), p.help);
        }
    }
    println!();
    println!(
        "Parameters go in a config file (`defrag --config FILE.toml`) as `[KIND.NAME]` tables,"
    );
    println!(
        "e.g. `[solver.slim]` then `max-iterations = 20`; `--solver slim,arap` is a fallback chain,"
    );
    println!(
        "and `--solver arap+slim` (the default) solves again with slim the refused merges of long seams."
    );
    Ok(())
}
