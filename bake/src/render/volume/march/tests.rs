use super::*;
use crate::input::mesh::shapes::{cuboid, icosphere};

/// Bakes a cube and a ball (16³, 600 points, exact solver) in a scratch directory.
fn small_bake(name: &str) -> Archives {
    let dir = std::env::temp_dir().join(format!("otbake-vrender-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    std::fs::write(dir.join("cube.obj"), cuboid([0.0; 3], [1.0; 3]).to_obj()).unwrap();
    std::fs::write(dir.join("ball.obj"), icosphere([0.0; 3], 1.0, 2).to_obj()).unwrap();
    let body = "[output]\ndir = \"out\"\n[proxy]\nkind = \"gaussian\"\nsamples = 600\n[solver]\nkind = \"exact\"\n[mesh]\nresolution = 16\nmargin = 0.2\n[[input]]\nname = \"cube\"\npath = \"cube.obj\"\n[[input]]\nname = \"ball\"\npath = \"ball.obj\"\n";
    std::fs::write(dir.join("m.toml"), body).unwrap();
    let m = crate::manifest::Manifest::load(&dir.join("m.toml")).unwrap();
    crate::pipeline::bake::bake(&m, &Default::default()).unwrap();
    Archives::load(&m).unwrap()
}

#[test]
fn skipping_empty_cells_changes_no_pixel() {
    let archives = small_bake("skip");
    let maps = archives.maps().unwrap();
    let blend = open(archives.proxy().unwrap(), &maps).unwrap();
    let s = RenderSettings {
        size: 32,
        sigma: 0.015,
        extinction: 5.0,
        ..Default::default()
    };
    let kernel = check_render(&s).unwrap();
    let (lo, hi) = scene_box(&blend, s.sigma).unwrap();
    let cam = Camera::new(lo, hi, &s);
    // The ball leaves the corners of its box empty.
    with_prepared(&blend, &[0.0, 1.0], |prep| {
        let occupancy = Occupancy::new(prep, lo, hi, s.sigma)?;
        let empty = occupancy.full.iter().filter(|f| !**f).count();
        assert!(empty > occupancy.full.len() / 4, "{empty} empty cells");
        let skipping = march(prep, &cam, &s, kernel, Some(&occupancy))?;
        let plain = march(prep, &cam, &s, kernel, None)?;
        assert_eq!(skipping, plain);
        // Something was drawn: some pixels differ from the background.
        assert!(plain
            .pixels
            .chunks(4)
            .any(|p| (p[0] - BACKGROUND[0]).abs() > 0.1));
        Ok(())
    })
    .unwrap();
}

#[test]
fn camera_rays_hit_the_box_they_frame() {
    let s = RenderSettings::default();
    let cam = Camera::new([0.2; 3], [0.8; 3], &s);
    // The center pixel's ray passes through the box center.
    let (o, t0, t1) = cam.ray(50, 50, 101).unwrap();
    let mid = add(o, scale(cam.forward, 0.5 * (t0 + t1)));
    for k in 0..3 {
        assert!((mid[k] - 0.5).abs() < 1e-9, "{mid:?}");
    }
    // The box's projection touches the frame but not every corner of it.
    assert!(cam.ray(0, 0, 101).is_none());
    let hits = (0..101).filter(|&x| cam.ray(x, 50, 101).is_some()).count();
    assert!(hits >= 95, "{hits} of 101 pixels of the middle row");
    // y is up: the top row of the image sees larger y than the bottom row.
    let top = cam.ray(50, 30, 101).unwrap();
    let bottom = cam.ray(50, 70, 101).unwrap();
    assert!(top.0[1] > bottom.0[1]);
    for x in [0, 7, 99] {
        let j = jitter(x, 3);
        assert!((0.0..1.0).contains(&j));
    }
}
