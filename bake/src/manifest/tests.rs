use super::*;
use crate::input::mesh::voxelize::Fit;
use crate::input::vol::VolFit;
use crate::solve::SlicedMap;
use otbake_formats::storage::Precision;
use std::path::PathBuf;

fn data_dir() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../shared/data/shapes")
}

fn manifest(body: &str) -> Result<Manifest, ManifestError> {
    let dir = data_dir();
    Manifest::parse(&dir.join("test.toml"), body)
}

const GOOD: &str = r#"
[output]
dir = "out"
[proxy]
kind = "gaussian"
samples = 1000
[solver]
kind = "sliced"
[[input]]
name = "duck"
path = "duck.png"
density = "inverted"
"#;

#[test]
fn good_manifest_resolves_paths_and_defaults() {
    let m = manifest(GOOD).unwrap();
    assert_eq!(m.output_dir, data_dir().join("out"));
    assert_eq!(m.inputs[0].path, data_dir().join("duck.png"));
    assert_eq!(m.inputs[0].density, DensityChannel::Inverted);
    assert_eq!(m.proxy.samples, 1000);
    assert_eq!(
        m.proxy.source,
        ProxySource::Shape(ProxyShape::Gaussian { sigma: 1.0 / 6.0 })
    );
}

#[test]
fn unknown_key_names_line_and_column() {
    let e = manifest(&GOOD.replace("samples = 1000", "samples = 1000\nsigmma = 0.2")).unwrap_err();
    assert_eq!((e.line, e.column), (7, 1), "{e}");
    assert!(e.message.contains("sigmma"), "{e}");
    assert!(e.to_string().contains("test.toml:7:1"), "{e}");
}

#[test]
fn bad_values_are_located() {
    let e = manifest(&GOOD.replace("samples = 1000", "samples = 0")).unwrap_err();
    assert_eq!(e.line, 6, "{e}");
    assert!(e.message.contains("out of range"));
    let e = manifest(&GOOD.replace("samples = 1000", "samples = 99999999999")).unwrap_err();
    assert_eq!(e.line, 6, "{e}");
    let e = manifest(&GOOD.replace("duck.png", "nope.png")).unwrap_err();
    assert_eq!(e.line, 11, "{e}");
    assert!(e.message.contains("does not exist"));
    let e = manifest(&GOOD.replace("duck.png", "duck.gif")).unwrap_err();
    assert!(e.message.contains("unsupported"), "{e}");
    let e = manifest(&GOOD.replace("\"inverted\"", "\"inverse\"")).unwrap_err();
    assert_eq!(e.line, 12, "{e}");
    let e = manifest(&GOOD.replace("kind = \"gaussian\"", "kind = \"uniform\"\nsigma = 0.1"))
        .unwrap_err();
    assert!(e.message.contains("only to kind"), "{e}");
    let e = manifest(&GOOD.replace("kind = \"gaussian\"", "kind = \"input\"")).unwrap_err();
    assert!(e.message.contains("proxy.input"), "{e}");
}

#[test]
fn sliced_map_defaults_to_the_flow_and_takes_assignment() {
    let sliced = |m: &Manifest| match &m.solver {
        SolverSettings::Sliced(s) => s.clone(),
        other => panic!("{other:?}"),
    };
    let m = manifest(GOOD).unwrap();
    assert_eq!(sliced(&m).map, SlicedMap::Flow);
    let with = |map: &str| {
        GOOD.replace(
            "kind = \"sliced\"",
            &format!("kind = \"sliced\"\nmap = {map}"),
        )
    };
    let flow = manifest(&with("\"flow\"")).unwrap();
    assert_eq!(sliced(&flow).map, SlicedMap::Flow);
    assert_eq!(flow.solver.fingerprint(), m.solver.fingerprint());
    let a = manifest(&with("\"assignment\"")).unwrap();
    assert_eq!(sliced(&a).map, SlicedMap::Assignment);
    assert_ne!(a.solver.fingerprint(), m.solver.fingerprint());
    // Each solver's own values only, at the value's line.
    let e = manifest(&with("\"barycentric\"")).unwrap_err();
    assert_eq!(e.line, 9, "{e}");
    assert!(
        e.message.contains("\"flow\"") && e.message.contains("\"assignment\""),
        "{e}"
    );
    let sk = GOOD.replace("kind = \"sliced\"", "kind = \"sinkhorn\"\nmap = \"flow\"");
    let e = manifest(&sk).unwrap_err();
    assert_eq!(e.line, 9, "{e}");
    assert!(e.message.contains("barycentric"), "{e}");
    let e = manifest(&GOOD.replace("kind = \"sliced\"", "kind = \"exact\"\nmap = \"flow\""))
        .unwrap_err();
    assert!(e.message.contains("only to kind"), "{e}");
    // Not on the torus.
    let e = manifest(&TEXTURES.replace(
        "kind = \"sliced\"",
        "kind = \"sliced\"\nmap = \"assignment\"",
    ))
    .unwrap_err();
    assert!(e.message.contains("torus"), "{e}");
}

#[test]
fn storage_defaults_to_full_and_takes_a_preset_and_overrides() {
    assert_eq!(manifest(GOOD).unwrap().storage, Storage::FULL);
    let m = manifest(&format!("{GOOD}[storage]\npreset = \"compact\"\n")).unwrap();
    assert_eq!(m.storage, Storage::COMPACT);
    let m = manifest(&format!(
        "{GOOD}[storage]\npreset = \"compact\"\npositions = \"u16\"\ncolors = \"none\"\n"
    ))
    .unwrap();
    assert_eq!(
        m.storage,
        Storage {
            positions: Precision::U16,
            node_boxes: Precision::U16,
            colors: None,
            node_colors: false,
            spacings: false,
        }
    );
    let m = manifest(&format!(
        "{GOOD}[storage]\npreset = \"compact\"\nspacings = true\n"
    ))
    .unwrap();
    assert_eq!(
        m.storage,
        Storage {
            spacings: true,
            ..Storage::COMPACT
        }
    );
    let m = manifest(&format!(
        "{GOOD}[storage]\nnode_boxes = \"u16\"\nnode_colors = false\n"
    ))
    .unwrap();
    assert_eq!(
        m.storage,
        Storage {
            node_boxes: Precision::U16,
            node_colors: false,
            ..Storage::FULL
        }
    );
}

#[test]
fn bad_storage_is_located() {
    let e = manifest(&format!("{GOOD}[storage]\npositions = \"u4\"\n")).unwrap_err();
    assert_eq!(e.line, 14, "{e}");
    assert!(e.message.contains("u4") && e.message.contains("u16"), "{e}");
    let e = manifest(&format!("{GOOD}[storage]\nnode_boxes = \"u8\"\n")).unwrap_err();
    assert_eq!(e.line, 14, "{e}");
    let e = manifest(&format!(
        "{GOOD}[storage]\ncolors = \"none\"\nnode_colors = true\n"
    ))
    .unwrap_err();
    assert_eq!(e.line, 15, "{e}");
    assert!(e.message.contains("needs colors"), "{e}");
    let e = manifest(&format!("{GOOD}[storage]\nprecision = \"u8\"\n")).unwrap_err();
    assert!(e.message.contains("unknown field"), "{e}");
}

#[test]
fn mesh_section_sets_resolution_margin_and_common_fit() {
    let body = GOOD
        .replace("duck.png", "../meshes/torus.obj")
        .replace("density = \"inverted\"\n", "")
        + "[[input]]\nname = \"cow\"\npath = \"../meshes/spot_triangulated.obj\"\n";
    let m = manifest(&body).unwrap();
    assert_eq!(m.inputs[0].kind, InputKind::Mesh);
    assert_eq!(m.inputs[0].options.mesh, Default::default());
    let m = manifest(&format!(
        "{body}[mesh]\nresolution = 32\nfit = \"common\"\nmargin = 0.1\n"
    ))
    .unwrap();
    let all = vec![m.inputs[0].path.clone(), m.inputs[1].path.clone()];
    for i in &m.inputs {
        assert_eq!(i.options.mesh.resolution, 32);
        assert_eq!(i.options.mesh.margin, 0.1);
        assert_eq!(i.options.mesh.fit, Fit::Common(all.clone()));
    }
    for (bad, key) in [
        ("resolution = 1", "mesh.resolution"),
        ("margin = 0.5", "mesh.margin"),
        ("fit = \"both\"", "both"),
        ("size = 3", "size"),
    ] {
        let e = manifest(&format!("{body}[mesh]\n{bad}\n")).unwrap_err();
        assert_eq!(e.line, 16, "{e}");
        assert!(e.message.contains(key), "{e}");
    }
    let e = manifest(&format!("{body}density = \"alpha\"\n")).unwrap_err();
    assert!(e.message.contains("3D input"), "{e}");
}

#[test]
fn volume_section_sets_the_fit() {
    let body = GOOD
        .replace("duck.png", "../volumes/smoke_44x45x53.vol")
        .replace("density = \"inverted\"\n", "");
    let m = manifest(&body).unwrap();
    assert_eq!(m.inputs[0].kind, InputKind::Volume);
    assert_eq!(m.inputs[0].options.volume_fit, VolFit::Stretch);
    let m = manifest(&format!("{body}[volume]\nfit = \"pad\"\n")).unwrap();
    assert_eq!(m.inputs[0].options.volume_fit, VolFit::Pad);
    let e = manifest(&format!("{body}[volume]\nfit = \"crop\"\n")).unwrap_err();
    assert_eq!(e.line, 13, "{e}");
    assert!(e.message.contains("crop"), "{e}");
}

const TEXTURES: &str = r#"
[output]
dir = "out"
[proxy]
kind = "uniform"
samples = 1000
[solver]
kind = "sliced"
[[input]]
name = "onyx"
path = "../textures/marble_onyx003_ambientcg_1k.jpg"
wrap = "periodic"
[[input]]
name = "slate"
path = "../textures/marble_slate_texturecan240_gray.png"
wrap = "periodic"
"#;

#[test]
fn wrap_defaults_to_clamp_and_periodic_is_per_input() {
    let m = manifest(GOOD).unwrap();
    assert_eq!(m.wrap(), Wrap::Clamp);
    assert_eq!(m.inputs[0].wrap, Wrap::Clamp);
    let m = manifest(TEXTURES).unwrap();
    assert_eq!(m.wrap(), Wrap::Periodic);
    assert!(m.inputs.iter().all(|i| i.wrap == Wrap::Periodic));
    let m =
        manifest(&TEXTURES.replace("kind = \"uniform\"", "kind = \"input\"\ninput = \"slate\""))
            .unwrap();
    assert_eq!(m.proxy.source, ProxySource::Input(1));
    let clamp = TEXTURES.replace("wrap = \"periodic\"", "wrap = \"clamp\"");
    assert_eq!(manifest(&clamp).unwrap().wrap(), Wrap::Clamp);
}

#[test]
fn bad_wraps_are_located_and_say_how_to_fix_them() {
    // Inputs disagree: the second one's default, then its explicit value.
    let second = TEXTURES.rfind("wrap = \"periodic\"").unwrap();
    let mut body = TEXTURES.to_string();
    body.replace_range(second..second + "wrap = \"periodic\"".len(), "");
    let e = manifest(&body).unwrap_err();
    assert_eq!((e.line, e.column), (14, 8), "{e}");
    assert!(
        e.message.contains("\"slate\"") && e.message.contains("(the default)"),
        "{e}"
    );
    assert!(e.message.contains("on every input"), "{e}");
    body.insert_str(second, "wrap = \"clamp\"");
    let e = manifest(&body).unwrap_err();
    assert_eq!((e.line, e.column), (16, 8), "{e}");
    assert!(!e.message.contains("(the default)"), "{e}");
    // Concentrated proxies cannot serve the torus.
    for kind in ["gaussian", "spiral"] {
        let e = manifest(&TEXTURES.replace("\"uniform\"", &format!("\"{kind}\""))).unwrap_err();
        assert_eq!(e.line, 5, "{e}");
        assert!(
            e.message.contains(kind) && e.message.contains("kind = \"uniform\""),
            "{e}"
        );
    }
    // Only images tile.
    let vol = GOOD
        .replace("duck.png", "../volumes/smoke_44x45x53.vol")
        .replace("density = \"inverted\"", "wrap = \"periodic\"");
    let e = manifest(&vol).unwrap_err();
    assert_eq!(e.line, 12, "{e}");
    assert!(
        e.message.contains("tileable images") && e.message.contains("remove `wrap`"),
        "{e}"
    );
    // Unknown values name the choices.
    let e = manifest(&TEXTURES.replacen("\"periodic\"", "\"repeat\"", 1)).unwrap_err();
    assert_eq!(e.line, 12, "{e}");
    assert!(
        e.message.contains("repeat") && e.message.contains("periodic"),
        "{e}"
    );
}
