//! `otbake plan`: the bake as a build graph of hermetic `bake-one` actions, for Ninja locally or a
//! remote-execution system (Bazel, Buck2) at scale; the Bazel BUILD file is
//! [`super::bazel`].
//!
//! Each action declares its inputs (the manifest, the input file — for a mesh under `fit = "common"`
//! every mesh file —, the proxy archive for maps, and for maps of a manifest whose proxy is an input
//! that input's file, which the proxy's key hashes) and its single output, and runs `otbake bake-one`, which reads nothing else and writes nothing else. The
//! Ninja rules use `restat = 1`: `bake-one` leaves a current output untouched, so editing one input's
//! line in the manifest rebakes that map only, even though every action depends on the manifest file.

use crate::input::mesh::voxelize::Fit;
use crate::input::InputKind;
use crate::manifest::{Manifest, ProxySource};
use crate::pipeline::bazel::{self, BazelError, BazelLabels};
use std::path::{Path, PathBuf};

/// Output format of a plan.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum Format {
    /// A `build.ninja` file.
    Ninja,
    /// `{"actions": [{"id", "argv", "inputs", "outputs"}]}`.
    Json,
    /// A `BUILD.bazel` file for the manifest's folder, calling `bake/bazel/otbake.bzl`.
    Bazel,
}

/// What `otbake plan` writes.
#[derive(Debug, Clone)]
pub struct PlanOptions<'a> {
    /// The otbake executable the Ninja and JSON actions run.
    pub otbake: &'a Path,
    /// The output format.
    pub format: Format,
    /// Where a Bazel plan finds the rules and the otbake binary.
    pub bazel: BazelLabels,
}

/// One hermetic action.
#[derive(Debug, Clone, PartialEq)]
pub struct PlannedAction {
    /// `proxy` or the input name.
    pub id: String,
    /// Command line (`argv[0]` is the otbake executable).
    pub argv: Vec<String>,
    /// Every file the action reads.
    pub inputs: Vec<PathBuf>,
    /// The one file it writes.
    pub outputs: Vec<PathBuf>,
}

fn abs(p: &Path) -> PathBuf {
    std::path::absolute(p).unwrap_or_else(|_| p.to_path_buf())
}

fn s(p: &Path) -> String {
    p.display().to_string()
}

/// The actions of a manifest, proxy first. Paths are absolute.
pub fn actions(m: &Manifest, otbake: &Path) -> Vec<PlannedAction> {
    let manifest = abs(&m.path);
    let proxy_out = abs(&m.proxy_archive());
    let mut proxy_inputs = vec![manifest.clone()];
    // The files the proxy's key hashes: an input proxy's file; for the barycenter, every input
    // (and, for meshes under the common box, every mesh: they are all inputs).
    let proxy_files: Vec<PathBuf> = match &m.proxy.source {
        ProxySource::Input(i) => vec![abs(&m.inputs[*i].path)],
        ProxySource::Barycenter(_) => m.inputs.iter().map(|i| abs(&i.path)).collect(),
        ProxySource::Shape(_) => Vec::new(),
    };
    proxy_inputs.extend(proxy_files.iter().cloned());
    let mut out = vec![PlannedAction {
        id: "proxy".into(),
        argv: vec![
            s(otbake),
            "bake-one".into(),
            s(&manifest),
            "--product".into(),
            "proxy".into(),
            "-o".into(),
            s(&proxy_out),
        ],
        inputs: proxy_inputs,
        outputs: vec![proxy_out.clone()],
    }];
    for input in &m.inputs {
        let o = abs(&m.map_archive(&input.name));
        let mut inputs = vec![manifest.clone(), abs(&input.path)];
        // A mesh placed by the common box reads every mesh input.
        if let (InputKind::Mesh, Fit::Common(all)) = (input.kind, &input.options.mesh.fit) {
            inputs.extend(all.iter().filter(|p| **p != input.path).map(|p| abs(p)));
        }
        // A map's key holds the proxy's key, which hashes the proxy's files.
        for f in &proxy_files {
            if !inputs.contains(f) {
                inputs.push(f.clone());
            }
        }
        inputs.push(proxy_out.clone());
        out.push(PlannedAction {
            id: input.name.clone(),
            argv: vec![
                s(otbake),
                "bake-one".into(),
                s(&manifest),
                "--product".into(),
                input.name.clone(),
                "--proxy".into(),
                s(&proxy_out),
                "-o".into(),
                s(&o),
            ],
            inputs,
            outputs: vec![o],
        });
    }
    out
}

/// Escapes a path for a Ninja build line.
fn ninja_path(p: &Path) -> String {
    s(p).replace('$', "$$")
        .replace(' ', "$ ")
        .replace(':', "$:")
}

/// Quotes an argument for the POSIX shell Ninja runs commands with.
fn shell(arg: &str) -> String {
    if arg
        .chars()
        .all(|c| c.is_ascii_alphanumeric() || "/._-+=,".contains(c))
    {
        arg.to_string()
    } else {
        format!("'{}'", arg.replace('\'', "'\\''")).replace('$', "$$")
    }
}

/// The plan as text in `opts.format`. Only a Bazel plan can fail (an input outside the package).
pub fn render(m: &Manifest, opts: &PlanOptions<'_>) -> Result<String, BazelError> {
    let actions = actions(m, opts.otbake);
    Ok(match opts.format {
        Format::Bazel => bazel::render(m, &opts.bazel)?,
        Format::Json => {
            let list: Vec<_> = actions
                .iter()
                .map(|a| {
                    serde_json::json!({
                        "id": a.id,
                        "argv": a.argv,
                        "inputs": a.inputs.iter().map(|p| s(p)).collect::<Vec<_>>(),
                        "outputs": a.outputs.iter().map(|p| s(p)).collect::<Vec<_>>(),
                    })
                })
                .collect();
            format!(
                "{}\n",
                serde_json::to_string_pretty(&serde_json::json!({ "actions": list }))
                    .unwrap_or_default()
            )
        }
        Format::Ninja => {
            let mut t = format!(
                "# Generated by `otbake plan {}`: run with `ninja -f FILE`.\nninja_required_version = 1.7\n\n\
                 rule otbake\n  command = $cmd\n  description = otbake bake-one $id\n  restat = 1\n\n",
                s(&m.path)
            );
            for a in &actions {
                let outs: Vec<_> = a.outputs.iter().map(|p| ninja_path(p)).collect();
                let ins: Vec<_> = a.inputs.iter().map(|p| ninja_path(p)).collect();
                let cmd: Vec<_> = a.argv.iter().map(|x| shell(x)).collect();
                t += &format!(
                    "build {}: otbake {}\n  id = {}\n  cmd = {}\n\n",
                    outs.join(" "),
                    ins.join(" "),
                    a.id,
                    cmd.join(" ")
                );
            }
            let all: Vec<_> = actions
                .iter()
                .flat_map(|a| a.outputs.iter().map(|p| ninja_path(p)))
                .collect();
            t += &format!("default {}\n", all.join(" "));
            t
        }
    })
}
