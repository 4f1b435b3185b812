//! `deploy/` stays in step with the binaries:
//!
//! - every YAML file under `deploy/` parses (all documents of it), and every Kubernetes
//!   document names its `apiVersion` and `kind`;
//! - every command line in `deploy/` that runs `coordinator` or `worker` — systemd `Exec*=`
//!   lines (plus the `GAITSWEEP_*_ARGS=` flag lists of the env file), Kubernetes
//!   `command`/`args` (containers and exec probes), shell lines of the Slurm script and of the
//!   README's code blocks, Dockerfile `RUN` lines and `ENTRYPOINT` + `CMD` — uses only
//!   subcommands and `--flags` that the real binary's `--help` lists for that subcommand.
//!
//! The binaries are the ones built next to this test (`target/release/`), so run
//! `cargo build --release --workspace --bins` first.

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};
use std::process::Command;

use yaml_rust2::{Yaml, YamlLoader};

#[path = "deploy_check/shell.rs"]
mod shell;
use shell::{shell_tokens, Tok};

const BINARIES: [&str; 2] = ["coordinator", "worker"];

fn repo_root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .parent()
        .expect("tests/ has a parent")
        .to_path_buf()
}

fn deploy_dir() -> PathBuf {
    repo_root().join("deploy")
}

/// `target/release/NAME`, located from this test executable (`target/release/deps/deploy-*`).
fn binary(name: &str) -> PathBuf {
    let exe = std::env::current_exe().expect("current exe");
    let dir = exe
        .parent()
        .and_then(Path::parent)
        .expect("test executable lives in target/<profile>/deps");
    let path = dir.join(name);
    assert!(
        path.is_file(),
        "{} is missing: build the binaries first with `source scripts/setup.sh && cargo build --release --workspace --bins`",
        path.display()
    );
    path
}

/// Every file under `dir`, sorted.
fn files_under(dir: &Path) -> Vec<PathBuf> {
    let mut out = Vec::new();
    let mut stack = vec![dir.to_path_buf()];
    while let Some(d) = stack.pop() {
        for entry in std::fs::read_dir(&d).unwrap_or_else(|e| panic!("read {}: {e}", d.display())) {
            let path = entry.expect("dir entry").path();
            if path.is_dir() {
                stack.push(path);
            } else {
                out.push(path);
            }
        }
    }
    out.sort();
    out
}

fn rel(path: &Path) -> String {
    path.strip_prefix(repo_root())
        .unwrap_or(path)
        .display()
        .to_string()
}

fn read(path: &Path) -> String {
    std::fs::read_to_string(path).unwrap_or_else(|e| panic!("read {}: {e}", path.display()))
}

fn is_yaml(path: &Path) -> bool {
    matches!(
        path.extension().and_then(|e| e.to_str()),
        Some("yaml" | "yml")
    )
}

// ---------------------------------------------------------------------------------------
// Command lines
// ---------------------------------------------------------------------------------------

/// One invocation of a gaitsweep binary found in a deploy file.
#[derive(Debug, Clone)]
struct Invocation {
    /// Where it was found (file and line or YAML path).
    source: String,
    /// `coordinator` or `worker`.
    binary: String,
    /// The arguments after the binary.
    args: Vec<String>,
}

/// `/opt/gaitsweep/bin/worker` -> `worker`; `$DIR/coordinator` -> `coordinator`.
fn binary_name(word: &str) -> Option<&'static str> {
    let base = word.rsplit('/').next().unwrap_or(word);
    BINARIES.into_iter().find(|b| *b == base)
}

/// `gaitsweep-worker:0.1.0` or `registry/gaitsweep-coordinator` -> the image's entrypoint.
fn image_binary(word: &str) -> Option<&'static str> {
    let base = word.rsplit('/').next().unwrap_or(word);
    let name = base.split([':', '@']).next().unwrap_or(base);
    BINARIES
        .into_iter()
        .find(|b| name == format!("gaitsweep-{b}"))
}

/// Words that may stand before a binary in a command without being the command themselves.
fn is_prefix_word(word: &str) -> bool {
    matches!(
        word,
        "exec" | "env" | "srun" | "sudo" | "nohup" | "time" | "command" | "!"
    ) || word.starts_with('-')
        || word.split_once('=').is_some_and(|(k, _)| {
            !k.is_empty() && k.chars().all(|c| c.is_ascii_alphanumeric() || c == '_')
        })
}

/// `docker run` options that take no value.
const DOCKER_RUN_SWITCHES: [&str; 14] = [
    "-d",
    "--detach",
    "--rm",
    "-i",
    "-t",
    "-it",
    "-ti",
    "--interactive",
    "--tty",
    "--init",
    "--privileged",
    "--read-only",
    "-P",
    "--publish-all",
];

/// Invocations in one simple command (a run of words between operators).
fn invocations_in_command(words: &[String], source: &str, out: &mut Vec<Invocation>) {
    // `docker run [options] IMAGE [args]`: the args go to the image's entrypoint.
    if words.first().map(String::as_str) == Some("docker")
        && words.get(1).map(String::as_str) == Some("run")
    {
        // The image is the first word that is neither an option nor an option's value.
        let mut i = 2;
        while i < words.len() && words[i].starts_with('-') {
            let w = words[i].as_str();
            let takes_value = !w.contains('=') && !DOCKER_RUN_SWITCHES.contains(&w);
            i += if takes_value { 2 } else { 1 };
        }
        if let Some(binary) = words.get(i).and_then(|w| image_binary(w)) {
            out.push(Invocation {
                source: source.to_string(),
                binary: binary.to_string(),
                args: words[i + 1..].to_vec(),
            });
        }
        return;
    }
    // Anything after `--` (kubectl exec ... -- coordinator list) starts a new command.
    let mut start_ok = true;
    for (i, w) in words.iter().enumerate() {
        if w == "--" {
            start_ok = true;
        } else if let Some(b) = binary_name(w).filter(|_| start_ok) {
            out.push(Invocation {
                source: source.to_string(),
                binary: b.to_string(),
                args: words[i + 1..].to_vec(),
            });
            return;
        } else if !is_prefix_word(w) {
            start_ok = false;
        }
    }
}

/// Invocations in shell text; `first_line` numbers the text's first line in its file.
fn shell_invocations(text: &str, file: &str, first_line: usize, out: &mut Vec<Invocation>) {
    // Number commands by the line they start on: split into logical lines first.
    let mut logical = String::new();
    let mut logical_start = first_line;
    for (line_no, line) in (first_line..).zip(text.lines()) {
        if logical.is_empty() {
            logical_start = line_no;
        }
        if let Some(stripped) = line.strip_suffix('\\') {
            logical.push_str(stripped);
            logical.push(' ');
            continue;
        }
        logical.push_str(line);
        let source = format!("{file}:{logical_start}");
        let mut words = Vec::new();
        for tok in shell_tokens(&logical).into_iter().chain([Tok::Op]) {
            match tok {
                Tok::Word(w) => words.push(w),
                Tok::Op => {
                    invocations_in_command(&words, &source, out);
                    words.clear();
                }
            }
        }
        logical.clear();
    }
}

/// Fenced code blocks of a Markdown file, with a `$ ` prompt removed from their lines.
fn markdown_invocations(text: &str, file: &str, out: &mut Vec<Invocation>) {
    let mut in_block = false;
    let mut block = String::new();
    let mut block_start = 0;
    for (i, line) in text.lines().enumerate() {
        let trimmed = line.trim_start();
        if trimmed.starts_with("```") {
            if in_block {
                shell_invocations(&block, file, block_start, out);
                block.clear();
            } else {
                block_start = i + 2;
            }
            in_block = !in_block;
        } else if in_block {
            block.push_str(trimmed.strip_prefix("$ ").unwrap_or(trimmed));
            block.push('\n');
        }
    }
}

/// systemd units: `ExecStart=` and the other `Exec*=` lines (continued with `\\`).
fn systemd_invocations(text: &str, file: &str, out: &mut Vec<Invocation>) {
    let mut logical = String::new();
    let mut start = 0;
    for (i, line) in text.lines().enumerate() {
        if logical.is_empty() {
            start = i + 1;
        }
        if let Some(s) = line.strip_suffix('\\') {
            logical.push_str(s);
            logical.push(' ');
            continue;
        }
        logical.push_str(line);
        let entry = std::mem::take(&mut logical);
        let Some((key, value)) = entry.trim().split_once('=') else {
            continue;
        };
        if key.trim().starts_with("Exec") {
            // Command prefixes of systemd.service(5): - @ : + ! !!
            let value = value
                .trim_start()
                .trim_start_matches(['-', '@', ':', '+', '!']);
            shell_invocations(value, file, start, out);
        }
    }
}

/// `GAITSWEEP_WORKER_ARGS=...` / `GAITSWEEP_COORDINATOR_ARGS=...` (commented or not) in env
/// files and units: the extra flags the units append to `worker` / `coordinator serve`.
fn extra_args_invocations(text: &str, file: &str, out: &mut Vec<Invocation>) {
    for (i, line) in text.lines().enumerate() {
        let line = line.trim_start_matches(['#', ' ']);
        let line = line.strip_prefix("Environment=").unwrap_or(line);
        let (binary, mut args, value) = if let Some(v) = line.strip_prefix("GAITSWEEP_WORKER_ARGS=")
        {
            ("worker", vec![], v)
        } else if let Some(v) = line.strip_prefix("GAITSWEEP_COORDINATOR_ARGS=") {
            ("coordinator", vec!["serve".to_string()], v)
        } else {
            continue;
        };
        args.extend(shell_tokens(value).into_iter().filter_map(|t| match t {
            Tok::Word(w) => Some(w),
            Tok::Op => None,
        }));
        out.push(Invocation {
            source: format!("{file}:{}", i + 1),
            binary: binary.to_string(),
            args,
        });
    }
}

/// A Dockerfile's exec-form (`["a", "b"]`) or shell-form argument list.
fn dockerfile_words(value: &str) -> Vec<String> {
    let value = value.trim();
    if value.starts_with('[') {
        serde_json::from_str::<Vec<String>>(value)
            .unwrap_or_else(|e| panic!("bad exec-form JSON {value:?}: {e}"))
    } else {
        shell_tokens(value)
            .into_iter()
            .filter_map(|t| match t {
                Tok::Word(w) => Some(w),
                Tok::Op => None,
            })
            .collect()
    }
}

/// Dockerfiles: `RUN` lines as shell, and the last stage's `ENTRYPOINT` + `CMD`.
fn dockerfile_invocations(text: &str, file: &str, out: &mut Vec<Invocation>) {
    let mut entrypoint: Option<(usize, Vec<String>)> = None;
    let mut cmd: Option<(usize, Vec<String>)> = None;
    let mut logical = String::new();
    let mut start = 0;
    for (i, line) in text.lines().enumerate() {
        let trimmed = line.trim();
        if logical.is_empty() {
            if trimmed.starts_with('#') || trimmed.is_empty() {
                continue;
            }
            start = i + 1;
        } else if trimmed.starts_with('#') {
            continue; // comment lines inside a continued instruction
        }
        if let Some(s) = line.strip_suffix('\\') {
            logical.push_str(s);
            logical.push(' ');
            continue;
        }
        logical.push_str(line);
        let instr = std::mem::take(&mut logical);
        let (op, rest) = instr
            .trim()
            .split_once(char::is_whitespace)
            .unwrap_or((instr.trim(), ""));
        match op.to_ascii_uppercase().as_str() {
            "FROM" => {
                entrypoint = None;
                cmd = None;
            }
            "RUN" => {
                // Skip RUN options such as --mount=...; the rest is shell.
                let mut body = rest.trim_start();
                while body.starts_with("--") {
                    body = body
                        .split_once(char::is_whitespace)
                        .map_or("", |(_, r)| r)
                        .trim_start();
                }
                shell_invocations(body, file, start, out);
            }
            "ENTRYPOINT" => entrypoint = Some((start, dockerfile_words(rest))),
            "CMD" => cmd = Some((start, dockerfile_words(rest))),
            _ => {}
        }
    }
    let (line, mut words) = match (entrypoint, cmd) {
        (Some((l, e)), Some((_, c))) => (l, e.into_iter().chain(c).collect::<Vec<_>>()),
        (Some((l, e)), None) => (l, e),
        (None, Some((l, c))) => (l, c),
        (None, None) => return,
    };
    if words.first().is_some_and(|w| binary_name(w).is_some()) {
        let binary = binary_name(&words.remove(0)).expect("checked").to_string();
        out.push(Invocation {
            source: format!("{file}:{line} (ENTRYPOINT + CMD)"),
            binary,
            args: words,
        });
    }
}

fn yaml_strings(y: &Yaml) -> Option<Vec<String>> {
    y.as_vec()?
        .iter()
        .map(|v| match v {
            Yaml::String(s) | Yaml::Real(s) => Some(s.clone()),
            Yaml::Integer(i) => Some(i.to_string()),
            Yaml::Boolean(b) => Some(b.to_string()),
            _ => None,
        })
        .collect()
}

/// Kubernetes (or any YAML): every mapping with a `command` list that runs a binary,
/// followed by its `args`, or a `sh -c SCRIPT` command; containers that give only `args`
/// run their image's entrypoint.
fn yaml_invocations(doc: &Yaml, path: &str, out: &mut Vec<Invocation>) {
    match doc {
        Yaml::Hash(h) => {
            let get = |k: &str| h.get(&Yaml::String(k.to_string()));
            let command = get("command").and_then(yaml_strings);
            let args = get("args").and_then(yaml_strings).unwrap_or_default();
            let image = get("image").and_then(Yaml::as_str);
            match command {
                Some(cmd) if cmd.first().is_some_and(|c| binary_name(c).is_some()) => {
                    let binary = binary_name(&cmd[0]).expect("checked").to_string();
                    let all = cmd[1..].iter().cloned().chain(args).collect();
                    out.push(Invocation {
                        source: path.to_string(),
                        binary,
                        args: all,
                    });
                }
                Some(cmd) if cmd.len() >= 3 && cmd[0].ends_with("sh") && cmd[1] == "-c" => {
                    shell_invocations(&cmd[2], path, 1, out);
                }
                None if image.is_some_and(|i| image_binary(i).is_some())
                    && get("args").is_some() =>
                {
                    let binary = image_binary(image.expect("checked"))
                        .expect("checked")
                        .to_string();
                    out.push(Invocation {
                        source: path.to_string(),
                        binary,
                        args,
                    });
                }
                _ => {}
            }
            for (k, v) in h {
                let key = match k {
                    Yaml::String(s) => s.clone(),
                    other => format!("{other:?}"),
                };
                yaml_invocations(v, &format!("{path}.{key}"), out);
            }
        }
        Yaml::Array(a) => {
            for (i, v) in a.iter().enumerate() {
                yaml_invocations(v, &format!("{path}[{i}]"), out);
            }
        }
        _ => {}
    }
}

fn load_yaml(path: &Path) -> Vec<Yaml> {
    YamlLoader::load_from_str(&read(path))
        .unwrap_or_else(|e| panic!("{} is not valid YAML: {e}", rel(path)))
}

/// Every invocation of a gaitsweep binary in `deploy/`, and the files that must have one.
fn deploy_invocations() -> (Vec<Invocation>, Vec<String>) {
    let mut out = Vec::new();
    let mut must_have = Vec::new();
    for path in files_under(&deploy_dir()) {
        let file = rel(&path);
        let name = path
            .file_name()
            .and_then(|n| n.to_str())
            .unwrap_or_default()
            .to_string();
        let before = out.len();
        if is_yaml(&path) {
            for (i, doc) in load_yaml(&path).iter().enumerate() {
                let n = out.len();
                yaml_invocations(doc, &format!("{file} (document {})", i + 1), &mut out);
                let kind = doc["kind"].as_str().unwrap_or_default();
                if matches!(
                    kind,
                    "Deployment" | "StatefulSet" | "DaemonSet" | "Job" | "CronJob"
                ) {
                    assert!(out.len() > n, "{file} document {}: a {kind} that runs no gaitsweep binary with an explicit command", i + 1);
                }
            }
            continue;
        }
        if name.ends_with(".service") {
            systemd_invocations(&read(&path), &file, &mut out);
            extra_args_invocations(&read(&path), &file, &mut out);
        } else if name.ends_with(".env") || name.contains(".env.") {
            extra_args_invocations(&read(&path), &file, &mut out);
        } else if name.starts_with("Dockerfile") && !name.ends_with(".dockerignore") {
            dockerfile_invocations(&read(&path), &file, &mut out);
        } else if name.ends_with(".sbatch") || name.ends_with(".sh") {
            shell_invocations(&read(&path), &file, 1, &mut out);
        } else if name.ends_with(".md") {
            markdown_invocations(&read(&path), &file, &mut out);
            continue;
        } else {
            continue;
        }
        if out.len() == before {
            must_have.push(file);
        }
    }
    (out, must_have)
}

// ---------------------------------------------------------------------------------------
// The binaries' help
// ---------------------------------------------------------------------------------------

/// `--help` texts, run once per (binary, subcommand).
#[derive(Default)]
struct Help(BTreeMap<(String, Option<String>), String>);

impl Help {
    fn get(&mut self, binary: &str, sub: Option<&str>) -> &str {
        self.0
            .entry((binary.to_string(), sub.map(str::to_string)))
            .or_insert_with(|| {
                let mut cmd = Command::new(binary_path(binary));
                cmd.args(sub)
                    .arg("--help")
                    .env_remove("GAITSWEEP_TOKEN")
                    .env_remove("GAITSWEEP_URL");
                let out = cmd
                    .output()
                    .unwrap_or_else(|e| panic!("run {binary} --help: {e}"));
                assert!(
                    out.status.success(),
                    "`{binary} {} --help` failed: {}",
                    sub.unwrap_or(""),
                    String::from_utf8_lossy(&out.stderr)
                );
                String::from_utf8(out.stdout).expect("help is UTF-8")
            })
    }

    /// Subcommand names listed under `Commands:` of the top-level help.
    fn subcommands(&mut self, binary: &str) -> BTreeSet<String> {
        let text = self.get(binary, None);
        text.lines()
            .skip_while(|l| !l.starts_with("Commands:"))
            .skip(1)
            .take_while(|l| !l.trim().is_empty())
            .filter_map(|l| l.split_whitespace().next().map(str::to_string))
            .collect()
    }
}

fn binary_path(name: &str) -> PathBuf {
    binary(name)
}

/// Whether `flag` (`--name` or `-x`) is an option in the help text.
fn help_lists(help: &str, flag: &str) -> bool {
    help.match_indices(flag).any(|(i, _)| {
        let before_ok = i == 0 || help[..i].ends_with([' ', '\n', ',', '[', '(']);
        let after = help[i + flag.len()..].chars().next();
        before_ok && !after.is_some_and(|c| c.is_ascii_alphanumeric() || c == '-' || c == '_')
    })
}

/// The problems of one invocation: an unknown subcommand, or flags its help does not list.
fn check(help: &mut Help, inv: &Invocation) -> Vec<String> {
    let subs = help.subcommands(&inv.binary);
    let first = inv.args.first().map(String::as_str);
    let sub = match first {
        Some(s) if subs.contains(s) => Some(s),
        Some(s) if !s.starts_with('-') && !s.starts_with('$') => {
            return vec![format!(
                "{}: `{} {s}`: {s:?} is not a subcommand of {} (its --help lists: {})",
                inv.source,
                inv.binary,
                inv.binary,
                subs.iter().cloned().collect::<Vec<_>>().join(", ")
            )];
        }
        _ => None,
    };
    let text = help.get(&inv.binary, sub).to_string();
    let shown = format!(
        "{}{}",
        inv.binary,
        sub.map(|s| format!(" {s}")).unwrap_or_default()
    );
    inv.args
        .iter()
        .skip(usize::from(sub.is_some()))
        .filter(|a| a.starts_with('-') && a.len() > 1 && *a != "--")
        // values such as `-3.5` or `-$(X)` are not flags
        .filter(|a| !a[1..].starts_with(|c: char| c.is_ascii_digit() || c == '.' || c == '$'))
        .map(|a| {
            a.split('=')
                .next()
                .expect("split yields one part")
                .to_string()
        })
        .filter(|flag| !help_lists(&text, flag))
        .map(|flag| {
            format!(
                "{}: `{shown}` does not accept {flag} (not in `{shown} --help`)",
                inv.source
            )
        })
        .collect()
}

// ---------------------------------------------------------------------------------------
// Tests
// ---------------------------------------------------------------------------------------

#[test]
fn every_yaml_file_in_deploy_parses() {
    let yamls: Vec<PathBuf> = files_under(&deploy_dir())
        .into_iter()
        .filter(|p| is_yaml(p))
        .collect();
    assert!(
        !yamls.is_empty(),
        "no YAML files under {}",
        deploy_dir().display()
    );
    let mut problems = Vec::new();
    for path in &yamls {
        match YamlLoader::load_from_str(&read(path)) {
            Err(e) => problems.push(format!("{}: invalid YAML: {e}", rel(path))),
            Ok(docs) => {
                if docs.is_empty() {
                    problems.push(format!("{}: no YAML document", rel(path)));
                }
                for (i, doc) in docs.iter().enumerate() {
                    if !matches!(doc, Yaml::Hash(_)) {
                        problems.push(format!("{} document {}: not a mapping", rel(path), i + 1));
                    } else if rel(path).starts_with("deploy/k8s") {
                        for key in ["apiVersion", "kind"] {
                            if doc[key].as_str().is_none_or(str::is_empty) {
                                problems.push(format!(
                                    "{} document {}: no {key}",
                                    rel(path),
                                    i + 1
                                ));
                            }
                        }
                    }
                }
            }
        }
    }
    assert!(
        problems.is_empty(),
        "YAML problems in deploy/:\n{}",
        problems.join("\n")
    );
}

#[test]
fn every_command_line_in_deploy_uses_flags_the_binaries_accept() {
    let (invocations, without) = deploy_invocations();
    assert!(
        without.is_empty(),
        "these deploy files run no coordinator or worker command that this test could find \
         (write the binary's name, e.g. /opt/gaitsweep/bin/worker, not a variable): {without:?}"
    );
    for binary in BINARIES {
        assert!(
            invocations.iter().any(|i| i.binary == binary),
            "no `{binary}` command line found in deploy/"
        );
    }
    let mut help = Help::default();
    let mut problems = Vec::new();
    for inv in &invocations {
        problems.extend(check(&mut help, inv));
    }
    let listing: Vec<String> = invocations
        .iter()
        .map(|i| format!("  {}: {} {}", i.source, i.binary, i.args.join(" ")))
        .collect();
    println!(
        "checked {} command lines:\n{}",
        invocations.len(),
        listing.join("\n")
    );
    assert!(
        problems.is_empty(),
        "deploy/ uses flags the binaries do not accept:\n{}",
        problems.join("\n")
    );
}

/// The checker itself fails on what it must fail on, for every kind of file it reads.
#[test]
fn the_checker_catches_bad_flags_and_subcommands() {
    let mut found = Vec::new();
    systemd_invocations(
        "[Service]\nExecStart=/opt/gaitsweep/bin/worker --connect ${URL} \\\n  --bogus-flag 1\n",
        "unit",
        &mut found,
    );
    shell_invocations(
        "set -e\nsrun --nodes=2 --cpus-per-task=4 \"$H/bin/worker\" --threads 4 --bogus-flag\n",
        "sbatch",
        1,
        &mut found,
    );
    dockerfile_invocations(
        "FROM x AS b\nCMD [\"nope\"]\nFROM y\nRUN worker --version && echo worker\nENTRYPOINT [\"coordinator\"]\nCMD [\"serve\", \"--bogus-flag\"]\n",
        "Dockerfile",
        &mut found,
    );
    let k8s = YamlLoader::load_from_str(
        "spec:\n  containers:\n    - command: [worker]\n      args: [--connect, http://c:50051, --bogus-flag]\n      \
         readinessProbe: {exec: {command: [coordinator, list, --bogus-flag]}}\n",
    )
    .unwrap();
    yaml_invocations(&k8s[0], "k8s", &mut found);
    markdown_invocations(
        "text\n```sh\n$ coordinator reportx SWEEP\nkubectl exec pod -- coordinator list --bogus-flag\n\
         docker run -d --name gaitsweep-worker -e A=b --rm gaitsweep-worker:1 --bogus-flag\n```\n",
        "md",
        &mut found,
    );
    extra_args_invocations(
        "#GAITSWEEP_WORKER_ARGS=--threads 16 --bogus-flag\n",
        "env",
        &mut found,
    );

    let mut help = Help::default();
    let by_source: BTreeMap<&str, Vec<String>> = found
        .iter()
        .map(|inv| (inv.source.as_str(), check(&mut help, inv)))
        .collect();
    let shown = format!("{found:#?}");
    // `worker --version` is fine; every other invocation must be refused.
    assert_eq!(found.len(), 10, "{shown}");
    let ok: Vec<&&str> = by_source
        .iter()
        .filter(|(_, p)| p.is_empty())
        .map(|(s, _)| s)
        .collect();
    assert_eq!(
        ok,
        vec![&"Dockerfile:4"],
        "only `RUN worker --version` is valid: {by_source:#?}"
    );
    for (source, problems) in &by_source {
        if *source != "Dockerfile:4" {
            assert!(
                problems
                    .iter()
                    .any(|p| p.contains("--bogus-flag")
                        || p.contains("\"reportx\" is not a subcommand")),
                "{source}: {problems:?}"
            );
        }
    }
    // A flag that is the prefix of a real one is not taken for it.
    let prefix = Invocation {
        source: "p".into(),
        binary: "worker".into(),
        args: vec!["--conn".into()],
    };
    assert_eq!(check(&mut help, &prefix).len(), 1);
}
