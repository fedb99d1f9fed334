//! Write → open round trips and every kind of damage the opener must refuse.

use otbake_formats::map::Map;
use otbake_formats::open::{open_map, open_proxy};
use otbake_formats::proxy::Proxy;
use otbake_formats::tree::{depth, fill_node_boxes, fill_node_sums, node_count};
use otbake_formats::write::{aligned_copy, encode_map, encode_proxy};
use otbake_formats::FormatError;

fn sample_archives() -> (Vec<u8>, Vec<u8>) {
    let n = 37u32;
    let dim = 2;
    let leaf = 4;
    let d = depth(n, leaf);
    let nodes = node_count(d) as usize;
    let pos: Vec<f32> = (0..n as usize * dim)
        .map(|i| (i as f32 * 0.618).fract())
        .collect();
    let mut boxes = vec![0.0; nodes * 2 * dim];
    fill_node_boxes(&pos, dim, d, &mut boxes);
    let proxy = Proxy {
        dim: dim as u32,
        n,
        leaf_size: leaf,
        depth: d,
        key: [7; 32],
        description: "test",
        positions: &pos,
        node_boxes: &boxes,
    };
    let colors: Vec<f32> = (0..n as usize * 3).map(|i| i as f32).collect();
    let mut sums = vec![0.0; nodes * 3];
    fill_node_sums(&colors, 3, d, &mut sums);
    let map = Map {
        dim: dim as u32,
        n,
        depth: d,
        proxy_key: [7; 32],
        key: [9; 32],
        composite: 0,
        mean_mass: 0.5,
        positions: &pos,
        colors: &colors,
        node_boxes: &boxes,
        node_colors: &sums,
        solver_report: "none",
        transport_cost: 0.0,
    };
    (
        encode_proxy(&proxy).unwrap().to_vec(),
        encode_map(&map).unwrap().to_vec(),
    )
}

#[test]
fn round_trip() {
    let (p, m) = sample_archives();
    let p = aligned_copy(&p);
    let m = aligned_copy(&m);
    let proxy = open_proxy(&p).unwrap();
    assert_eq!(proxy.n, 37);
    assert_eq!(proxy.positions.len(), 74);
    let map = open_map(&m).unwrap();
    assert_eq!(map.n, 37);
    assert_eq!(
        map.node_colors[0].to_native(),
        (0..37).map(|i| 3 * i).sum::<i32>() as f32
    );
    // A proxy is not a map.
    assert!(matches!(open_map(&p), Err(FormatError::WrongKind { .. })));
}

#[test]
fn damage_is_refused_without_panic() {
    let (_, m) = sample_archives();
    for cut in 0..m.len() {
        assert!(
            open_map(&aligned_copy(&m[..cut])).is_err(),
            "truncated at {cut}"
        );
    }
    for i in 0..m.len() {
        for bit in [0u8, 3, 7] {
            let mut b = m.clone();
            b[i] ^= 1 << bit;
            assert!(
                open_map(&aligned_copy(&b)).is_err(),
                "flip at byte {i} bit {bit}"
            );
        }
    }
    let mut v = m.clone();
    v[8] = 2;
    assert!(matches!(
        open_map(&aligned_copy(&v)),
        Err(FormatError::WrongVersion { found: 2 })
    ));
    let mut t = m.clone();
    t.extend_from_slice(&[0; 16]);
    assert!(matches!(
        open_map(&aligned_copy(&t)),
        Err(FormatError::LengthMismatch { .. })
    ));
}
