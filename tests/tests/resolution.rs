//! `samples = { resolution = N }`: the baker derives n from the output resolution by the rule the
//! bench's error-vs-n curve supports (`otbake::sample::resolution`), so a small scene bakes far
//! fewer samples than a large one.

use otbake::manifest::Manifest;
use otbake::pipeline::bake::{bake, BakeOptions};
use otbake::render::Archives;
use otbake::sample::resolution::SAMPLES_PER_CELL;
use otbake_tests::{scratch, shared_data, write_manifest};

fn body(samples: &str) -> String {
    let mut b = format!(
        "[output]\ndir = \"out\"\n[proxy]\nkind = \"gaussian\"\nsamples = {samples}\n[solver]\nkind = \"exact\"\n"
    );
    for s in ["heart", "duck"] {
        b += &format!(
            "[[input]]\nname = \"{s}\"\npath = \"{}\"\ndensity = \"inverted\"\n",
            shared_data().join(format!("shapes/{s}.png")).display()
        );
    }
    b
}

#[test]
fn a_small_scene_bakes_far_fewer_samples_than_a_large_one() {
    let dir = scratch("resolution");
    let parse = |r: u64| {
        Manifest::parse(
            &dir.join("m.toml"),
            &body(&format!("{{ resolution = {r} }}")),
        )
        .unwrap_or_else(|e| panic!("{e}"))
    };
    let (small, large) = (parse(64), parse(1024));
    assert_eq!(small.proxy.samples as u64, SAMPLES_PER_CELL * 64 * 64);
    assert_eq!(large.proxy.samples as u64, SAMPLES_PER_CELL * 1024 * 1024);
    assert_eq!(large.proxy.samples, 256 * small.proxy.samples);
    assert_eq!(small.proxy.resolution, Some(64));
    // A count is still a count, and the rule's n is the n a bake makes.
    assert_eq!(
        Manifest::parse(&dir.join("m.toml"), &body("1234"))
            .unwrap()
            .proxy
            .samples,
        1234
    );
    let m = write_manifest(&dir, "m.toml", &body("{ resolution = 16 }"));
    let m = Manifest::load(&m).unwrap();
    bake(&m, &BakeOptions::default()).unwrap();
    let archives = Archives::load(&m).unwrap();
    assert_eq!(
        archives.proxy().unwrap().n() as u64,
        SAMPLES_PER_CELL * 16 * 16
    );
}

#[test]
fn bad_resolutions_are_errors_at_their_line() {
    let dir = scratch("resolution-bad");
    for (samples, want) in [
        ("{ resolution = 0 }", "out of range"),
        ("{ resolution = 5000 }", "lower the resolution"),
        ("{ res = 64 }", "unknown field `res`"),
        ("{ }", "needs `resolution = N`"),
        ("\"many\"", "a sample count"),
    ] {
        let e = Manifest::parse(&dir.join("m.toml"), &body(samples)).unwrap_err();
        assert!(e.message.contains(want) && e.line == 5, "{samples}: {e}");
    }
}
