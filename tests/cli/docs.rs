//! Docs that run (issue 42): every code block of README.md and docs/*.md is checked
//! against the program, and a block that drifts fails naming its page and line.
//!
//! What each kind of block gets (the line before a fence may say `<!-- check: KIND … -->`):
//!
//! - ```` ```console ````: each `$ hilcam …` line runs (in a sandbox holding the repository's
//!   `scenes/`, `config/`, `docs/`, `examples/` and `scripts/`, plus the page's `file`
//!   blocks); its stdout and stderr must be the lines shown: `[..]` matches any text within
//!   a line, a `...` line any number of lines, a first line `? failed` a non-zero exit.
//! - ```` ```sh ````: commands without output. `hilcam` commands (also `cargo run --release
//!   --`) must name real subcommands and flags (checked against `--help`), and every
//!   repository path any command names must exist.
//! - ```` ```toml ````: loaded by the real loaders: `scene` (a whole scene file;
//!   `render-defaults`: its `[render]` table shows the defaults), `scene-fragment` (tables
//!   merged into a minimal scene), `serve-fragment` (merged into a minimal serve config;
//!   `gige-defaults`: its `[output.gige]` is `GigeConfig::default()`), `camera` (a camera
//!   file), `file NAME` (written into the sandbox for the page's console blocks).
//! - ```` ```json ````: `frames-jsonl` (each line a `FrameRecord`, every key read back),
//!   `frames-jsonl-object` (a `"key": {…}` member of one), `session` (a session file).
//! - ```` ```rust ````: compiled here (`rust_snippets`): the block must be this file's text.
//! - other blocks: `paths` (the first word of each line is a repository path), `trajectory`
//!   (loaded as a trajectory file), `bytes TEST` (a worked byte dump that TEST decodes and
//!   compares byte for byte), `python TEST` (a Python example that TEST, a pytest file,
//!   runs against the installed module), `diagram` (a layout drawing, nothing to run),
//!   `file NAME`.
//!
//! Besides, the serve config's defaults that docs/serve-config.md states in its tables
//! are loaded and compared with the keys left out (`serve_config_defaults_are_the_documented_ones`).
//!
//! `cargo test --test cli docs::` runs them all.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::Command;

const HILCAM: &str = env!("CARGO_BIN_EXE_hilcam");

/// The pages checked: README.md and every docs/*.md.
fn pages() -> Vec<PathBuf> {
    let mut v: Vec<PathBuf> = std::fs::read_dir("docs")
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == "md"))
        .collect();
    v.sort();
    v.insert(0, PathBuf::from("README.md"));
    v
}

/// One fenced code block.
#[derive(Debug)]
struct Block {
    page: PathBuf,
    /// Line of the opening fence (1-based).
    line: usize,
    info: String,
    /// The `<!-- check: … -->` words on the line before the fence.
    check: Vec<String>,
    lines: Vec<String>,
}

impl Block {
    fn at(&self) -> String {
        format!("{}:{}", self.page.display(), self.line)
    }

    fn kind(&self) -> &str {
        self.check.first().map_or("", String::as_str)
    }

    fn text(&self) -> String {
        self.lines.iter().map(|l| format!("{l}\n")).collect()
    }
}

fn blocks(page: &Path) -> Vec<Block> {
    let text = std::fs::read_to_string(page).unwrap();
    let lines: Vec<&str> = text.lines().collect();
    let mut out = Vec::new();
    let mut i = 0;
    while i < lines.len() {
        let t = lines[i].trim_start();
        if let Some(info) = t.strip_prefix("```") {
            let indent = lines[i].len() - t.len();
            let check = i
                .checked_sub(1)
                .and_then(|j| lines[j].trim().strip_prefix("<!-- check:"))
                .and_then(|c| c.strip_suffix("-->"))
                .map(|c| c.split_whitespace().map(str::to_string).collect())
                .unwrap_or_default();
            let start = i;
            i += 1;
            let mut body = Vec::new();
            while i < lines.len() && !lines[i].trim_start().starts_with("```") {
                body.push(lines[i].get(indent..).unwrap_or(lines[i].trim_start()).to_string());
                i += 1;
            }
            out.push(Block {
                page: page.to_path_buf(),
                line: start + 1,
                info: info.trim().to_string(),
                check,
                lines: body,
            });
        }
        i += 1;
    }
    out
}

/// A directory that looks like the repository's root to the commands of one page.
struct Sandbox {
    dir: tempfile::TempDir,
}

impl Sandbox {
    fn new() -> Sandbox {
        let dir = tempfile::tempdir().unwrap();
        let repo = std::env::current_dir().unwrap();
        for d in ["config", "docs", "examples", "scripts"] {
            std::os::unix::fs::symlink(repo.join(d), dir.path().join(d)).unwrap();
        }
        // A real scenes/ of links, so that scene snippets can be written beside the shipped
        // ones and reach `meshes/`, `stars/` and `../config/` as the shipped scenes do.
        std::fs::create_dir(dir.path().join("scenes")).unwrap();
        for e in std::fs::read_dir(repo.join("scenes")).unwrap() {
            let e = e.unwrap();
            std::os::unix::fs::symlink(e.path(), dir.path().join("scenes").join(e.file_name())).unwrap();
        }
        Sandbox { dir }
    }

    fn path(&self) -> &Path {
        self.dir.path()
    }

    fn write(&self, name: &str, text: &str) -> PathBuf {
        let p = self.path().join(name);
        std::fs::write(&p, text).unwrap();
        p
    }
}

/// Shell words of a command line: whitespace-separated, with '…' and "…" quoting.
fn words(line: &str) -> Vec<String> {
    let mut out = Vec::new();
    let (mut cur, mut quote, mut any) = (String::new(), None, false);
    for c in line.chars() {
        match (quote, c) {
            (None, '\'' | '"') => {
                quote = Some(c);
                any = true;
            }
            (Some(q), c) if c == q => quote = None,
            (None, c) if c.is_whitespace() => {
                if any {
                    out.push(std::mem::take(&mut cur));
                    any = false;
                }
            }
            (_, c) => {
                cur.push(c);
                any = true;
            }
        }
    }
    if any {
        out.push(cur);
    }
    out
}

/// The commands of a block: `\`-continued lines joined, comments (` # …`) cut.
fn commands(lines: &[String], prompt: Option<&str>) -> Vec<(usize, String)> {
    let mut out: Vec<(usize, String)> = Vec::new();
    let mut cont = false;
    for (k, l) in lines.iter().enumerate() {
        let body = if cont {
            Some(l.trim())
        } else {
            match prompt {
                Some(p) => l.strip_prefix(p),
                None => Some(l.as_str()),
            }
        };
        let Some(body) = body else { continue };
        let body = match body.find(" #") {
            Some(i) => &body[..i],
            None if body.trim_start().starts_with('#') => "",
            None => body,
        };
        let (body, more) = match body.trim_end().strip_suffix('\\') {
            Some(b) => (b, true),
            None => (body, false),
        };
        if cont {
            out.last_mut().unwrap().1.push_str(&format!(" {}", body.trim()));
        } else if !body.trim().is_empty() {
            out.push((k, body.trim().to_string()));
        }
        cont = more;
    }
    out
}

/// The simple commands of a command line (split at `&&`, `||`, `|`, `;`).
fn simple_commands(w: &[String]) -> Vec<&[String]> {
    w.split(|t| ["&&", "||", "|", ";"].contains(&t.as_str())).filter(|c| !c.is_empty()).collect()
}

/// The hilcam arguments of a simple command, if it runs hilcam: `hilcam …`,
/// `target/…/hilcam …`, `/usr/bin/time -v hilcam …`, `cargo run --release -- …`.
fn hilcam_args(w: &[String]) -> Option<Vec<String>> {
    let first = w.first()?;
    if first == "hilcam" || first.ends_with("/hilcam") {
        return Some(w[1..].to_vec());
    }
    if first == "time" || first.ends_with("/time") || first == "exec" {
        let k = 1 + w[1..].iter().take_while(|t| t.starts_with('-')).count();
        return hilcam_args(&w[k..]);
    }
    if w.get(1).is_some_and(|t| t == "run") && first == "cargo" {
        let dashes = w.iter().position(|t| t == "--")?;
        return Some(w[dashes + 1..].to_vec());
    }
    None
}

/// Help texts by subcommand path, cached.
#[derive(Default)]
struct Helps(BTreeMap<Vec<String>, String>);

impl Helps {
    fn get(&mut self, path: &[String]) -> &str {
        self.0.entry(path.to_vec()).or_insert_with(|| {
            let out = Command::new(HILCAM).args(path).arg("--help").output().unwrap();
            assert!(out.status.success(), "hilcam {} --help failed", path.join(" "));
            String::from_utf8(out.stdout).unwrap()
        })
    }

    /// The subcommands a help text lists.
    fn subcommands(help: &str) -> Vec<String> {
        let Some(at) = help.find("Commands:") else { return Vec::new() };
        help[at..]
            .lines()
            .skip(1)
            .take_while(|l| l.starts_with("  "))
            .filter_map(|l| l.split_whitespace().next().map(str::to_string))
            .collect()
    }
}

/// A `hilcam` command's subcommands and flags exist.
fn check_hilcam_command(at: &str, args: &[String], helps: &mut Helps) {
    let args: Vec<String> = args
        .iter()
        .map(|a| a.trim_matches(|c| c == '[' || c == ']').to_string())
        .filter(|a| !a.is_empty() && a != "…")
        .collect();
    let mut path: Vec<String> = Vec::new();
    let mut i = 0;
    while i < args.len() {
        let a = &args[i];
        if a == "--log" {
            i += 2;
            continue;
        }
        let subs = Helps::subcommands(helps.get(&path));
        if subs.contains(a) {
            path.push(a.clone());
            i += 1;
        } else {
            break;
        }
    }
    assert!(!path.is_empty(), "{at}: `hilcam {}`: no such subcommand", args.join(" "));
    let help = helps.get(&path).to_string();
    for a in &args[i..] {
        let Some(flag) = a.strip_prefix("--") else { continue };
        let name = flag.split('=').next().unwrap();
        let named = help.match_indices(&format!("--{name}")).any(|(k, m)| {
            help[k + m.len()..].chars().next().is_none_or(|c| !(c.is_alphanumeric() || c == '-' || c == '_'))
        });
        assert!(named || name == "log", "{at}: `hilcam {}` has no flag --{name}", path.join(" "));
    }
}

/// Every repository path a command names exists.
fn check_paths(at: &str, w: &[String]) {
    const ROOTS: [&str; 9] =
        ["scenes/", "config/", "scripts/", "docs/", "examples/", "tests/", "crates/", "fuzz/", "benches/"];
    const OUTPUTS: [&str; 5] = ["--out", "--csv", "--preview", "--histogram-png", "--samples-map"];
    for (k, t) in w.iter().enumerate() {
        let t = t.trim_matches(|c| c == '[' || c == ']' || c == ',');
        let t = t.split_once('=').map_or(t, |(_, v)| v);
        if ROOTS.iter().any(|r| t.starts_with(r)) && !t.contains('*') && !t.contains('$') {
            let p = Path::new(t.split(':').next().unwrap());
            // What a command writes need not exist yet: its directory must.
            let written = k > 0 && OUTPUTS.contains(&w[k - 1].trim_start_matches('['));
            let there = if written { p.parent().is_some_and(Path::exists) } else { p.exists() };
            assert!(there, "{at}: `{t}` is not in the repository");
        }
    }
}

/// `expected` (with `...` lines and `[..]` within lines) matches `actual`.
fn lines_match(expected: &[&str], actual: &[&str]) -> bool {
    match expected.split_first() {
        None => actual.is_empty(),
        Some((&"...", rest)) => (0..=actual.len()).any(|k| lines_match(rest, &actual[k..])),
        Some((e, rest)) => {
            actual.split_first().is_some_and(|(a, arest)| line_matches(e, a) && lines_match(rest, arest))
        }
    }
}

/// One line, trailing blanks aside (a page keeps none).
fn line_matches(expected: &str, actual: &str) -> bool {
    let (expected, actual) = (expected.trim_end(), actual.trim_end());
    let parts: Vec<&str> = expected.split("[..]").collect();
    if parts.len() == 1 {
        return expected == actual;
    }
    let (first, last) = (parts[0], parts[parts.len() - 1]);
    if !actual.starts_with(first) || actual.len() < first.len() + last.len() || !actual.ends_with(last) {
        return false;
    }
    let mut rest = &actual[first.len()..actual.len() - last.len()];
    for p in &parts[1..parts.len() - 1] {
        match rest.find(p) {
            Some(k) => rest = &rest[k + p.len()..],
            None => return false,
        }
    }
    true
}

/// Run a console block's commands in `sandbox` and compare their output.
fn run_console(b: &Block, sandbox: &Sandbox, tally: &mut Tally) {
    let cmds = commands(&b.lines, Some("$ "));
    assert!(!cmds.is_empty(), "{}: a console block without a `$ ` command", b.at());
    for (n, (k, cmd)) in cmds.iter().enumerate() {
        let at = format!("{}:{}", b.page.display(), b.line + 1 + k);
        let end = cmds.get(n + 1).map_or(b.lines.len(), |c| c.0);
        // The shown output: the lines after the command and its `\`-continued lines.
        let continued = b.lines[*k..end].iter().take_while(|l| l.trim_end().ends_with('\\')).count();
        let mut shown: Vec<&str> = b.lines[k + 1 + continued..end].iter().map(String::as_str).collect();
        let fails = shown.first() == Some(&"? failed");
        if fails {
            shown.remove(0);
        }
        let w = words(cmd);
        let args = hilcam_args(&w)
            .filter(|_| simple_commands(&w).len() == 1)
            .unwrap_or_else(|| panic!("{at}: console commands are one hilcam command each: `{cmd}`"));
        let t0 = std::time::Instant::now();
        let out =
            Command::new(HILCAM).args(&args).current_dir(sandbox.path()).env_remove("HILCAM_LOG").output().unwrap();
        tally.command(&at, t0.elapsed());
        let text = format!("{}{}", String::from_utf8_lossy(&out.stdout), String::from_utf8_lossy(&out.stderr));
        let actual: Vec<&str> = text.lines().collect();
        assert_eq!(!out.status.success(), fails, "{at}: `{cmd}` exit status {} (output:\n{text})", out.status);
        assert!(lines_match(&shown, &actual), "{at}: `{cmd}` printed\n{text}\nthe page shows\n{}", shown.join("\n"));
    }
}

/// Check the `sh` block's commands; how many there were.
fn check_sh(b: &Block, helps: &mut Helps) -> usize {
    let cmds = commands(&b.lines, None);
    for (k, cmd) in &cmds {
        let at = format!("{}:{}", b.page.display(), b.line + 1 + k);
        let w = words(cmd);
        check_paths(&at, &w);
        for c in simple_commands(&w) {
            if let Some(args) = hilcam_args(c) {
                check_hilcam_command(&at, &args, helps);
            }
        }
    }
    cmds.len()
}

/// A minimal scene around a fragment: the nav1024 camera, the shipped plate, a material.
fn scene_around(fragment: &str) -> String {
    let mut head = String::new();
    if !fragment.contains("[camera]") && !fragment.contains("camera_file") {
        head.push_str("camera_file = \"../config/cameras/nav1024.toml\"\n");
    }
    let material = fragment
        .lines()
        .find_map(|l| l.trim().strip_prefix("materials.").or_else(|| l.trim().strip_prefix("[materials.")))
        .map(|r| r.split([' ', ']', '=']).next().unwrap().to_string());
    let mut tail = String::from("\n[[mesh]]\nobj = \"meshes/plate.obj\"\n");
    match material {
        Some(m) => tail.push_str(&format!("material = \"{m}\"\n")),
        None => tail.push_str("[materials.white_paint]\nmodel = \"lambert\"\nrho = 0.5\n"),
    }
    format!("{head}{fragment}{tail}")
}

fn load_scene(b: &Block, sandbox: &Sandbox, text: &str) -> hilcam_core::scene::Scene {
    let p = sandbox.write(&format!("scenes/doc_{}.toml", b.line), text);
    hilcam_core::scene::load(&p).unwrap_or_else(|e| panic!("{}: the scene does not load: {e}\n{text}", b.at()))
}

/// The text without its `[name]` table.
fn without_table(text: &str, name: &str) -> String {
    let mut out = String::new();
    let mut inside = false;
    for l in text.lines() {
        if l.starts_with('[') {
            inside = l.split('#').next().unwrap().trim() == format!("[{name}]");
        }
        if !inside {
            out.push_str(l);
            out.push('\n');
        }
    }
    out
}

fn check_toml(b: &Block, sandbox: &Sandbox) {
    let text = b.text();
    match b.kind() {
        "scene" => {
            let scene = load_scene(b, sandbox, &text);
            if b.check.iter().any(|c| c == "render-defaults") {
                let bare = load_scene(b, sandbox, &without_table(&text, "render"));
                assert_eq!(
                    format!("{:?}", scene.render),
                    format!("{:?}", bare.render),
                    "{}: the [render] values shown are not the defaults",
                    b.at()
                );
            }
        }
        "scene-fragment" => {
            load_scene(b, sandbox, &scene_around(&text));
        }
        "serve-fragment" => {
            let scene = std::env::current_dir().unwrap().join("scenes/plate.toml");
            let cfg = format!("scene = {:?}\n{text}", scene.display().to_string());
            let p = sandbox.write(&format!("serve_{}.toml", b.line), &cfg);
            let c = hilcam_core::serve::config::ServeConfig::load(&p)
                .unwrap_or_else(|e| panic!("{}: the serve config does not load: {e}", b.at()));
            if b.check.iter().any(|c| c == "gige-defaults") {
                assert_eq!(
                    c.output.gige,
                    Some(hilcam_core::sink::gige::GigeConfig::default()),
                    "{}: the [output.gige] values shown are not the defaults",
                    b.at()
                );
            }
        }
        "camera" => {
            let p = sandbox.write(&format!("camera_{}.toml", b.line), &text);
            let preset = hilcam_core::scene::file::load_camera_file(&p)
                .unwrap_or_else(|e| panic!("{}: the camera file does not load: {e}", b.at()));
            hilcam_core::sensor::Sensor::new(&preset.camera, &preset.sensor)
                .unwrap_or_else(|e| panic!("{}: the camera file's sensor is refused: {e}", b.at()));
        }
        "file" => {}
        k => panic!(
            "{}: a toml block needs <!-- check: scene | scene-fragment | serve-fragment | camera | file NAME --> (has `{k}`)",
            b.at()
        ),
    }
}

/// Every key of the documented JSON object is one the program writes back.
fn keys_read_back(at: &str, doc: &serde_json::Value, back: &serde_json::Value, path: &str) {
    if let (Some(d), Some(b)) = (doc.as_object(), back.as_object()) {
        for (k, v) in d {
            let sub = format!("{path}.{k}");
            let got = b.get(k).unwrap_or_else(|| panic!("{at}: `{sub}` is not a field the program reads"));
            keys_read_back(at, v, got, &sub);
        }
    }
}

fn check_json(b: &Block, first_record: &mut Option<String>) {
    use hilcam_core::sink::recorder::FrameRecord;
    let record = |at: &str, line: &str| {
        let r: FrameRecord = serde_json::from_str(line).unwrap_or_else(|e| panic!("{at}: not a frame record: {e}"));
        let doc: serde_json::Value = serde_json::from_str(line).unwrap();
        keys_read_back(at, &doc, &serde_json::to_value(&r).unwrap(), "");
    };
    match b.kind() {
        "frames-jsonl" => {
            for (k, l) in b.lines.iter().enumerate() {
                record(&format!("{}:{}", b.page.display(), b.line + 1 + k), l);
                first_record.get_or_insert_with(|| l.clone());
            }
        }
        "frames-jsonl-object" => {
            let base = first_record.as_ref().unwrap_or_else(|| panic!("{}: no frames-jsonl line before it", b.at()));
            let line = format!("{},{}}}", base.trim_end().strip_suffix('}').unwrap(), b.text().trim());
            record(&b.at(), &line);
        }
        "session" => {
            hilcam_core::session::Session::parse(&b.text(), &b.page)
                .unwrap_or_else(|e| panic!("{}: not a session file: {e}", b.at()));
        }
        k => panic!(
            "{}: a json block needs <!-- check: frames-jsonl | frames-jsonl-object | session --> (has `{k}`)",
            b.at()
        ),
    }
}

fn check_other(b: &Block) {
    match b.kind() {
        "paths" => {
            for (k, l) in b.lines.iter().enumerate() {
                let path = l.split_whitespace().next().unwrap_or("");
                for p in path.split(", ") {
                    let p = p.trim_end_matches(',');
                    assert!(
                        Path::new(p).exists() || Path::new("crates/hilcam-core/src").join(p).exists(),
                        "{}:{}: `{p}` does not exist",
                        b.page.display(),
                        b.line + 1 + k
                    );
                }
            }
        }
        "trajectory" => {
            hilcam_core::pose::trajectory::Trajectory::parse(&b.text(), &b.page)
                .unwrap_or_else(|e| panic!("{}: not a trajectory file: {e}", b.at()));
        }
        kind @ ("bytes" | "python") => {
            let test = b.check.get(1).unwrap_or_else(|| panic!("{}: `{kind}` names the test that runs it", b.at()));
            let src = std::fs::read_to_string(test).unwrap_or_else(|_| panic!("{}: no test file {test}", b.at()));
            assert!(
                src.contains(&b.page.display().to_string()),
                "{}: {test} does not read {}",
                b.at(),
                b.page.display()
            );
        }
        "diagram" | "file" => {}
        k => panic!(
            "{}: a ```{} block needs <!-- check: paths | trajectory | bytes TEST | python TEST | diagram | file NAME --> (has `{k}`)",
            b.at(),
            b.info
        ),
    }
}

/// How many blocks of each kind ran, and the commands' time.
#[derive(Default)]
struct Tally {
    kinds: BTreeMap<String, usize>,
    commands: usize,
    /// Shell commands checked (not run).
    shell: usize,
    time: std::time::Duration,
    slowest: (std::time::Duration, String),
}

impl Tally {
    fn block(&mut self, kind: &str) {
        *self.kinds.entry(kind.to_string()).or_default() += 1;
    }

    fn command(&mut self, at: &str, t: std::time::Duration) {
        self.commands += 1;
        self.time += t;
        if t > self.slowest.0 {
            self.slowest = (t, at.to_string());
        }
    }
}

#[test]
fn every_code_block_of_the_docs_runs_or_loads() {
    let t0 = std::time::Instant::now();
    let mut helps = Helps::default();
    let mut tally = Tally::default();
    for page in pages() {
        let sandbox = Sandbox::new();
        let mut first_record = None;
        for b in blocks(&page) {
            if b.kind() == "file" {
                let name = b.check.get(1).unwrap_or_else(|| panic!("{}: `file` needs a NAME", b.at()));
                sandbox.write(name, &b.text());
            }
            match b.info.as_str() {
                "console" => run_console(&b, &sandbox, &mut tally),
                "sh" => tally.shell += check_sh(&b, &mut helps),
                "toml" => check_toml(&b, &sandbox),
                "json" => check_json(&b, &mut first_record),
                "rust" => {
                    // Compared word by word: rustfmt may indent and space the copy here.
                    let squash = |t: &str| t.split_whitespace().collect::<Vec<_>>().join(" ");
                    let here = squash(&std::fs::read_to_string(file!()).unwrap());
                    assert!(
                        here.contains(&squash(&b.text())),
                        "{}: the Rust snippet is not one tests/cli/docs.rs compiles (mod rust_snippets)",
                        b.at()
                    );
                }
                _ => check_other(&b),
            }
            tally.block(format!("{} {}", b.info, b.kind()).trim());
        }
    }
    let blocks: usize = tally.kinds.values().sum();
    eprintln!(
        "docs: {blocks} code blocks checked ({:?}); {} shell commands checked; {} commands ran in {:.1} s (slowest {:.1} s at {}); {:.1} s in all",
        tally.kinds,
        tally.shell,
        tally.commands,
        tally.time.as_secs_f64(),
        tally.slowest.0.as_secs_f64(),
        tally.slowest.1,
        t0.elapsed().as_secs_f64()
    );
}

/// The literal defaults of docs/serve-config.md's tables (`| key | type | default | … |`
/// under `## \`[section]\``), each set explicitly, load to the config the key's absence
/// gives.
#[test]
fn serve_config_defaults_are_the_documented_ones() {
    use hilcam_core::serve::config::ServeConfig;
    let page = std::fs::read_to_string("docs/serve-config.md").unwrap();
    let dir = tempfile::tempdir().unwrap();
    let load = |text: &str| {
        let p = dir.path().join("s.toml");
        std::fs::write(&p, format!("scene = \"scene.toml\"\n{text}")).unwrap();
        ServeConfig::load(&p).map(|c| format!("{c:?}"))
    };
    let (mut section, mut checked) = (String::new(), 0);
    for (n, l) in page.lines().enumerate() {
        if let Some(h) = l.strip_prefix("## `[") {
            section = h.split(']').next().unwrap().to_string();
            continue;
        }
        let cells: Vec<&str> = l.split(" | ").map(|c| c.trim_matches(|c| c == '|' || c == ' ')).collect();
        if section.is_empty() || section == "input" || cells.len() < 4 || !cells[0].starts_with('`') {
            continue;
        }
        let key = cells[0].trim_matches('`');
        let default = cells[2];
        // Literal defaults only: a number, true / false, or one backticked value.
        let value = if default.parse::<f64>().is_ok() || default == "true" || default == "false" {
            default.to_string()
        } else if default.starts_with('`') && default.ends_with('`') && default.matches('`').count() == 2 {
            let v = default.trim_matches('`');
            if v.parse::<toml::Value>().is_ok() || v.starts_with('"') || v.starts_with('[') {
                v.to_string()
            } else {
                format!("{v:?}")
            }
        } else {
            continue;
        };
        let base = if section == "record" { "[record]\ndir = \"d\"\n".to_string() } else { format!("[{section}]\n") };
        let without = load(&base).unwrap_or_else(|e| panic!("docs/serve-config.md:{}: [{section}] alone: {e}", n + 1));
        let with = load(&format!("{base}{key} = {value}\n"))
            .unwrap_or_else(|e| panic!("docs/serve-config.md:{}: {section}.{key} = {value}: {e}", n + 1));
        assert_eq!(with, without, "docs/serve-config.md:{}: {section}.{key}'s default is not {value}", n + 1);
        checked += 1;
    }
    assert!(checked >= 20, "only {checked} defaults found: has the table layout changed?");
    eprintln!("docs: {checked} serve-config defaults checked");
}

/// The Rust snippets of the docs, compiled (never called: they need a scene, a mesh or a
/// frame at hand). Each block's text must appear here.
#[allow(dead_code, unused_variables)]
mod rust_snippets {
    use hilcam_core::render::film::RadianceImage;
    use hilcam_core::render::geometry::TriMesh;
    use hilcam_core::scene::fold::{FoldError, FoldLevel};
    use hilcam_core::sensor::{Sensor, SensorError};

    /// docs/sensor.md, "Monte Carlo noise and the sensor".
    fn sensor_md(
        sensor: &Sensor,
        radiance: RadianceImage,
        variance: Vec<f32>,
        seed: u64,
        t_s: f64,
        k: f64,
    ) -> Result<(), SensorError> {
        let out = sensor.apply_with_variance(&radiance, Some(&variance), seed, t_s, k)?;
        let mc = out.stats.mc; // Some(McNoiseStats) with a detector and DN output
        let bound = sensor.noise_bound(t_s, k); // for the renderer's quality = "sensor"
        let e2 = sensor.mc_variance_e2(&variance, t_s)?; // per-pixel e⁻² (None without a detector)
        let dn2 = sensor.mc_variance_output(&variance, t_s)?; // per-pixel, in the output's units²
        let at = sensor.mc_noise_stats(&radiance, &variance, t_s, 0.25)?; // the report at another k, unconverted
        Ok(())
    }

    /// docs/folds.md, "The statistic".
    fn folds_md(mesh: TriMesh, mli_index: u32, seed: u64) -> Result<TriMesh, FoldError> {
        use hilcam_core::scene::fold;
        let fit = fold::fit_for_edge(FoldLevel::Medium.target(), seed, 0.01)?; // < 1 s
        let folded = fold::wrap_faces(&mesh, &[mli_index], &fit.params, seed, 0.01);
        Ok(folded)
    }
}
