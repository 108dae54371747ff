//! The command-line reference, from the program's clap definition.

use std::fmt::Write as _;

use super::{cell, generated_header};

/// One argument's row: the flag or value name, its values, default and help.
fn argument_row(arg: &clap::Arg) -> String {
    let name = match (arg.get_long(), arg.get_short()) {
        (Some(long), Some(short)) => format!("`-{short}`, `--{long}`"),
        (Some(long), None) => format!("`--{long}`"),
        (None, Some(short)) => format!("`-{short}`"),
        (None, None) => format!("`{}`", arg.get_id().as_str().to_uppercase()),
    };
    let takes_value = arg.get_action().takes_values();
    let value = if !takes_value {
        String::new()
    } else {
        let possible: Vec<String> = arg
            .get_possible_values()
            .iter()
            .filter(|v| !v.is_hide_set())
            .map(|v| format!("`{}`", v.get_name()))
            .collect();
        if possible.is_empty() {
            arg.get_value_names()
                .map(|names| {
                    let names: Vec<String> = names.iter().map(|n| n.to_string()).collect();
                    format!("`{}`", names.join(" "))
                })
                .unwrap_or_else(|| format!("`{}`", arg.get_id().as_str().to_uppercase()))
        } else {
            possible.join(", ")
        }
    };
    let default: Vec<String> = arg
        .get_default_values()
        .iter()
        .map(|v| format!("`{}`", v.to_string_lossy()))
        .collect();
    let repeat = matches!(arg.get_action(), clap::ArgAction::Append);
    let help = arg
        .get_long_help()
        .or_else(|| arg.get_help())
        .map(|h| h.to_string())
        .unwrap_or_default();
    let help = if repeat && !help.contains("repeatable") {
        format!("{help} (repeatable)")
    } else {
        help
    };
    format!(
        "| {name} | {value} | {} | {} |\n",
        default.join(", "),
        cell(&help)
    )
}

/// Writes `command` (as `path`) and then each of its subcommands.
fn write_command(out: &mut String, command: &clap::Command, path: &str) {
    let _ = writeln!(out, "## `{path}`\n");
    if let Some(about) = command.get_long_about().or_else(|| command.get_about()) {
        let _ = writeln!(out, "{}\n", cell(&about.to_string()));
    }
    let mut usage_command = command.clone().bin_name(path);
    let usage = usage_command.render_usage().to_string();
    let usage = usage.trim_start_matches("Usage:").trim();
    let _ = writeln!(out, "```text\n{usage}\n```\n");
    let args: Vec<&clap::Arg> = command
        .get_arguments()
        .filter(|a| !a.is_hide_set() && !matches!(a.get_id().as_str(), "help" | "version"))
        .collect();
    if !args.is_empty() {
        out.push_str("| argument | value | default | meaning |\n|---|---|---|---|\n");
        for arg in args {
            out.push_str(&argument_row(arg));
        }
        out.push('\n');
    }
    for sub in command.get_subcommands().filter(|s| !s.is_hide_set()) {
        if sub.get_name() == "help" {
            continue;
        }
        write_command(out, sub, &format!("{path} {}", sub.get_name()));
    }
}

/// `reference/cli.md`: every command, flag, value and default of `cli`.
pub fn cli_page(cli: &clap::Command) -> String {
    let mut cli = cli.clone();
    cli.build();
    let mut out = generated_header("the command line's definition (`src/main.rs`)");
    out.push_str(
        "# Command line\n\n\
         Every command and flag of `omnicave`, as `omnicave COMMAND --help` prints them. \
         Flags that override a config key take precedence over the config file for that run; \
         what they accept is validated like the file (see [Config keys](config.md)).\n\n",
    );
    write_command(&mut out, &cli, "omnicave");
    out
}
