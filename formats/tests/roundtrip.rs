//! Write → open round trips and every kind of damage the opener must refuse.

use otbake_formats::map::Map;
use otbake_formats::open::{open_map, open_proxy};
use otbake_formats::proxy::Proxy;
use otbake_formats::storage::{Precision, Storage};
use otbake_formats::tree::{depth, fill_node_boxes, internal_count, node_count};
use otbake_formats::view::MapView;
use otbake_formats::write::{
    aligned_copy, encode_map, encode_map_content, encode_proxy, MapContent,
};
use otbake_formats::{FormatError, Wrap};

fn content<'a>(pos: &'a [f32], colors: &'a [f32], d: u32) -> MapContent<'a> {
    MapContent {
        dim: 2,
        depth: d,
        proxy_key: [7; 32],
        key: [9; 32],
        composite: 0,
        mean_mass: 0.5,
        wrap: Wrap::Clamp,
        positions: pos,
        colors,
        spacings: &[],
        solver_report: "none",
        transport_cost: 0.0,
    }
}

fn sample_data() -> (Vec<f32>, Vec<f32>, u32) {
    let n = 37u32;
    let pos: Vec<f32> = (0..n as usize * 2)
        .map(|i| (i as f32 * 0.618).fract())
        .collect();
    let colors: Vec<f32> = (0..n as usize * 3).map(|i| i as f32).collect();
    (pos, colors, depth(n, 4))
}

fn sample_archives_with(storage: Storage) -> (Vec<u8>, Vec<u8>) {
    let (pos, colors, d) = sample_data();
    let n = 37u32;
    let dim = 2;
    let nodes = node_count(d) as usize;
    let mut boxes = vec![0.0; nodes * 2 * dim];
    fill_node_boxes(&pos, dim, d, &mut boxes);
    let proxy = Proxy {
        dim: dim as u32,
        n,
        leaf_size: 4,
        depth: d,
        key: [7; 32],
        wrap: 0,
        description: "test",
        positions: &pos,
        node_boxes: &boxes,
    };
    (
        encode_proxy(&proxy).unwrap().to_vec(),
        encode_map_content(&content(&pos, &colors, d), storage)
            .unwrap()
            .to_vec(),
    )
}

fn sample_archives() -> (Vec<u8>, Vec<u8>) {
    sample_archives_with(Storage::FULL)
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
    // Only internal nodes have stored boxes and sums.
    let d = map.depth.to_native();
    assert_eq!(map.node_boxes.len(), internal_count(d) as usize * 4 * 4);
    assert_eq!(map.node_colors.len(), internal_count(d) as usize * 3);
    // Full precision decodes to exactly what was written.
    let (pos, colors, _) = sample_data();
    let view = MapView::new(map).unwrap();
    for i in 0..37 {
        assert_eq!(&view.position(i)[..2], &pos[i * 2..i * 2 + 2]);
        assert_eq!(&view.color(i)[..], &colors[i * 3..i * 3 + 3]);
    }
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
    // Archives of the previous format versions (1: f32 only, stored leaf boxes; 2: no wrap code;
    // 3: no spacings) are refused.
    for old in [1u8, 2, 3] {
        let mut v = m.clone();
        v[8] = old;
        assert!(matches!(
            open_map(&aligned_copy(&v)),
            Err(FormatError::WrongVersion { found }) if found == old as u32
        ));
    }
    let mut t = m.clone();
    t.extend_from_slice(&[0; 16]);
    assert!(matches!(
        open_map(&aligned_copy(&t)),
        Err(FormatError::LengthMismatch { .. })
    ));
}

#[test]
fn every_storage_round_trips_within_its_bounds() {
    let (pos, colors, _) = sample_data();
    for positions in [Precision::F32, Precision::U16, Precision::U8] {
        for node_boxes in [Precision::F32, Precision::U16] {
            for c in [
                None,
                Some(Precision::F32),
                Some(Precision::U16),
                Some(Precision::U8),
            ] {
                for node_colors in [false, true] {
                    let s = Storage {
                        positions,
                        node_boxes,
                        colors: c,
                        node_colors: node_colors && c.is_some(),
                        // The sample content has no spacings, so none are stored.
                        spacings: false,
                    };
                    let (_, m) = sample_archives_with(s);
                    let m = aligned_copy(&m);
                    let view = MapView::open(&m).unwrap();
                    assert_eq!(view.storage(), s);
                    let cerr = view.color_error();
                    for i in 0..37 {
                        let (p, e) = (view.position(i), view.position_error(i));
                        for k in 0..2 {
                            assert!((p[k] - pos[i * 2 + k]).abs() <= e[k], "{s:?} point {i}");
                        }
                        let col = view.color(i);
                        for ch in 0..3 {
                            let full = if c.is_some() { colors[i * 3 + ch] } else { 0.0 };
                            assert!((col[ch] - full).abs() <= cerr[ch], "{s:?} color {i}");
                        }
                    }
                }
            }
        }
    }
}

/// Hand-forged archives whose storage fields disagree are refused with the field's name.
#[test]
fn inconsistent_storage_fields_are_refused() {
    let (pos, _, d) = sample_data();
    let internal = internal_count(d) as usize;
    let boxes = vec![0u8; internal * 4 * 4];
    let posb: Vec<u8> = pos.iter().flat_map(|v| v.to_le_bytes()).collect();
    let forge = |codes: [u8; 4],
                 bounds: &[f32],
                 color_range: &[f32],
                 positions: &[u8],
                 colors: &[u8],
                 node_boxes: &[u8],
                 node_colors: &[f32]| {
        let bytes = encode_map(&Map {
            dim: 2,
            n: 37,
            depth: d,
            proxy_key: [7; 32],
            key: [9; 32],
            composite: 0,
            mean_mass: 0.5,
            wrap: 0,
            storage: [codes[0], codes[1], codes[2], codes[3], 0],
            bounds,
            color_range,
            positions,
            colors,
            node_boxes,
            node_colors,
            spacings: &[],
            node_spacings: &[],
            solver_report: "",
            transport_cost: 0.0,
        })
        .unwrap();
        match open_map(&bytes) {
            Err(FormatError::Inconsistent { field }) => field,
            other => panic!("expected a refusal, got {:?}", other.map(|_| ())),
        }
    };
    let b = [0.0f32, 0.0, 1.0, 1.0];
    let q8 = vec![0u8; 37 * 2];
    let c8 = vec![0u8; 37 * 3];
    let sums = vec![0.0f32; internal * 3];
    assert_eq!(
        forge([3, 0, 0, 0], &b, &[], &posb, &[], &boxes, &[]),
        "storage"
    );
    assert_eq!(
        forge([0, 0, 0, 1], &b, &[], &posb, &[], &boxes, &[]),
        "storage"
    );
    assert_eq!(
        forge([0, 0, 0, 0], &b[..3], &[], &posb, &[], &boxes, &[]),
        "bounds"
    );
    assert_eq!(
        forge(
            [0, 0, 0, 0],
            &[1.0, 0.0, 0.0, 1.0],
            &[],
            &posb,
            &[],
            &boxes,
            &[]
        ),
        "bounds"
    );
    assert_eq!(
        forge(
            [0, 0, 0, 0],
            &[f32::NAN, 0.0, 1.0, 1.0],
            &[],
            &posb,
            &[],
            &boxes,
            &[]
        ),
        "bounds"
    );
    // An infinite extent is refused where a grid lies on it (u16 boxes), allowed where not.
    let wide_bounds = [-f32::MAX, 0.0, f32::MAX, 1.0];
    let boxes16 = vec![0u8; internal * 4 * 2];
    assert_eq!(
        forge([0, 1, 0, 0], &wide_bounds, &[], &posb, &[], &boxes16, &[]),
        "bounds"
    );
    assert_eq!(
        forge([2, 0, 0, 0], &b, &[], &posb, &[], &boxes, &[]),
        "positions"
    );
    assert_eq!(
        forge([0, 0, 3, 0], &b, &[], &posb, &c8, &boxes, &[]),
        "color_range"
    );
    assert_eq!(
        forge(
            [0, 0, 3, 0],
            &b,
            &[1.0, 0.0, 0.0, 0.0, 1.0, 1.0],
            &posb,
            &c8,
            &boxes,
            &[]
        ),
        "color_range"
    );
    assert_eq!(
        forge([0, 0, 3, 0], &b, &[0.0; 6], &posb, &c8[1..], &boxes, &[]),
        "colors"
    );
    assert_eq!(
        forge([0, 1, 0, 0], &b, &[], &posb, &[], &boxes, &[]),
        "node_boxes"
    );
    assert_eq!(
        forge([0, 0, 3, 1], &b, &[0.0; 6], &posb, &c8, &boxes, &sums[1..]),
        "node_colors"
    );
    assert_eq!(
        forge([0, 0, 3, 0], &b, &[0.0; 6], &posb, &c8, &boxes, &sums),
        "node_colors"
    );
    let mut nan = sums.clone();
    nan[0] = f32::INFINITY;
    assert_eq!(
        forge([0, 0, 3, 1], &b, &[0.0; 6], &posb, &c8, &boxes, &nan),
        "node_colors"
    );
    // Quantized positions decode on f32 boxes: a box of infinite extent is refused.
    let mut wide: Vec<f32> = vec![0.0; internal * 4];
    wide[0] = -f32::MAX;
    wide[2] = f32::MAX;
    let wideb: Vec<u8> = wide.iter().flat_map(|v| v.to_le_bytes()).collect();
    assert_eq!(
        forge([2, 0, 0, 0], &b, &[], &q8, &[], &wideb, &[]),
        "node_boxes"
    );
    // The same box under f32 positions is fine (nothing decodes on it).
    let ok = encode_map(&Map {
        dim: 2,
        n: 37,
        depth: d,
        proxy_key: [7; 32],
        key: [9; 32],
        composite: 0,
        mean_mass: 0.5,
        wrap: 0,
        storage: [0, 0, 0, 0, 0],
        bounds: &b,
        color_range: &[],
        positions: &posb,
        colors: &[],
        node_boxes: &wideb,
        node_colors: &[],
        spacings: &[],
        node_spacings: &[],
        solver_report: "",
        transport_cost: 0.0,
    })
    .unwrap();
    assert!(open_map(&ok).is_ok());
    let ok = encode_map(&Map {
        dim: 2,
        n: 37,
        depth: d,
        proxy_key: [7; 32],
        key: [9; 32],
        composite: 0,
        mean_mass: 0.5,
        wrap: 0,
        storage: [0, 0, 0, 0, 0],
        bounds: &wide_bounds,
        color_range: &[],
        positions: &posb,
        colors: &[],
        node_boxes: &boxes,
        node_colors: &[],
        spacings: &[],
        node_spacings: &[],
        solver_report: "",
        transport_cost: 0.0,
    })
    .unwrap();
    assert!(open_map(&ok).is_ok());
}

/// Periodic archives: the wrap code round trips, unknown codes are refused, and a periodic proxy's
/// points must lie in [0,1) and a periodic map's lifts in [LIFT_MIN, LIFT_MAX], whatever the storage.
#[test]
fn wrap_codes_and_periodic_ranges_are_checked() {
    let (pos, colors, d) = sample_data();
    let n = 37u32;
    let nodes = node_count(d) as usize;
    let proxy = |pos: &[f32], wrap: u32| {
        let mut boxes = vec![0.0; nodes * 4];
        fill_node_boxes(pos, 2, d, &mut boxes);
        aligned_copy(
            &encode_proxy(&Proxy {
                dim: 2,
                n,
                leaf_size: 4,
                depth: d,
                key: [7; 32],
                wrap,
                description: "test",
                positions: pos,
                node_boxes: &boxes,
            })
            .unwrap(),
        )
    };
    let p = proxy(&pos, 1);
    assert_eq!(open_proxy(&p).unwrap().wrap, 1);
    assert_eq!(Wrap::from_code(1), Some(Wrap::Periodic));
    assert!(matches!(
        open_proxy(&proxy(&pos, 2)),
        Err(FormatError::Inconsistent { field: "wrap" })
    ));
    let mut outside = pos.clone();
    outside[5] = 1.0;
    assert!(open_proxy(&proxy(&outside, 0)).is_ok());
    assert!(matches!(
        open_proxy(&proxy(&outside, 1)),
        Err(FormatError::Inconsistent { field: "positions" })
    ));

    // Lifts of torus points: up to half a period outside the unit square is fine.
    let lifts: Vec<f32> = pos
        .iter()
        .enumerate()
        .map(|(i, &v)| v + [-0.49, 0.49, 0.0][i % 3])
        .collect();
    for storage in [Storage::FULL, Storage::COMPACT] {
        let map = |pos: &[f32], wrap: Wrap| {
            aligned_copy(
                &encode_map_content(
                    &MapContent {
                        wrap,
                        ..content(pos, &colors, d)
                    },
                    storage,
                )
                .unwrap(),
            )
        };
        let m = map(&lifts, Wrap::Periodic);
        let opened = open_map(&m).unwrap();
        assert_eq!(opened.wrap, Wrap::Periodic as u32);
        let mut far = lifts.clone();
        far[7] = 2.5;
        assert!(open_map(&map(&far, Wrap::Clamp)).is_ok(), "{storage:?}");
        assert!(
            matches!(
                open_map(&map(&far, Wrap::Periodic)),
                Err(FormatError::Inconsistent { .. })
            ),
            "{storage:?}"
        );
        far[7] = -1.5;
        assert!(
            matches!(
                open_map(&map(&far, Wrap::Periodic)),
                Err(FormatError::Inconsistent { .. })
            ),
            "{storage:?}"
        );
    }
    // An unknown wrap code in a forged map.
    let posb: Vec<u8> = pos.iter().flat_map(|v| v.to_le_bytes()).collect();
    let internal = internal_count(d) as usize;
    let mut boxes = vec![0.0f32; nodes * 4];
    fill_node_boxes(&pos, 2, d, &mut boxes);
    let boxb: Vec<u8> = boxes[..internal * 4]
        .iter()
        .flat_map(|v| v.to_le_bytes())
        .collect();
    for (wrap, ok) in [(0u32, true), (1, true), (7, false), (u32::MAX, false)] {
        let bytes = encode_map(&Map {
            dim: 2,
            n,
            depth: d,
            proxy_key: [7; 32],
            key: [9; 32],
            composite: 0,
            mean_mass: 0.5,
            wrap,
            storage: [0, 0, 0, 0, 0],
            bounds: &boxes[..4],
            color_range: &[],
            positions: &posb,
            colors: &[],
            node_boxes: &boxb,
            node_colors: &[],
            spacings: &[],
            node_spacings: &[],
            solver_report: "",
            transport_cost: 0.0,
        })
        .unwrap();
        match open_map(&bytes) {
            Ok(_) => assert!(ok, "wrap code {wrap} opened"),
            Err(e) => assert!(
                !ok && e == FormatError::Inconsistent { field: "wrap" },
                "{wrap}: {e}"
            ),
        }
    }
}

/// Spacings round trip as codes rounded up, each internal node keeps the largest code below it,
/// and archives whose spacing fields disagree (lengths, a node below one of its points' or
/// children's codes) are refused.
#[test]
fn spacings_round_trip_and_bad_spacings_are_refused() {
    use otbake_formats::spacing::{decode, encode_up};
    use otbake_formats::tree::{node_at, Node};
    let (pos, colors, d) = sample_data();
    let spacings: Vec<f32> = (0..37).map(|i| 0.001 * (1.0 + i as f32)).collect();
    for storage in [
        Storage::FULL,
        Storage {
            spacings: true,
            ..Storage::COMPACT
        },
    ] {
        let bytes = aligned_copy(
            &encode_map_content(
                &MapContent {
                    spacings: &spacings,
                    ..content(&pos, &colors, d)
                },
                storage,
            )
            .unwrap(),
        );
        let view = MapView::open(&bytes).unwrap();
        assert!(view.has_spacings());
        for (i, &s) in spacings.iter().enumerate() {
            assert_eq!(view.spacing(i), decode(encode_up(s)));
            assert!(view.spacing(i) >= s && view.spacing(i) <= s * 1.091);
        }
        for level in 0..d {
            for offset in 0..1u32 << level {
                let node: Node = node_at(37, level, offset);
                let most = node.range().map(|i| view.spacing(i)).fold(0.0f32, f32::max);
                assert_eq!(view.internal_spacing(node.index as usize), most);
            }
        }
    }
    let plain =
        aligned_copy(&encode_map_content(&content(&pos, &colors, d), Storage::FULL).unwrap());
    assert!(!MapView::open(&plain).unwrap().has_spacings());

    // Forged archives: a map of f32 fields with the given spacing fields.
    let internal = internal_count(d) as usize;
    let mut boxes = vec![0.0f32; node_count(d) as usize * 4];
    fill_node_boxes(&pos, 2, d, &mut boxes);
    let boxb: Vec<u8> = boxes[..internal * 4]
        .iter()
        .flat_map(|v| v.to_le_bytes())
        .collect();
    let posb: Vec<u8> = pos.iter().flat_map(|v| v.to_le_bytes()).collect();
    let forge = |stored: bool, spacings: &[u8], node_spacings: &[u8]| {
        let bytes = encode_map(&Map {
            dim: 2,
            n: 37,
            depth: d,
            proxy_key: [7; 32],
            key: [9; 32],
            composite: 0,
            mean_mass: 0.5,
            wrap: 0,
            storage: [0, 0, 0, 0, stored as u8],
            bounds: &[boxes[0], boxes[1], boxes[2], boxes[3]],
            color_range: &[],
            positions: &posb,
            colors: &[],
            node_boxes: &boxb,
            node_colors: &[],
            spacings,
            node_spacings,
            solver_report: "",
            transport_cost: 0.0,
        })
        .unwrap();
        open_map(&bytes).map(|_| ())
    };
    let codes: Vec<u8> = (0..37).map(|i| 100 + i as u8).collect();
    let mut nodes = vec![0u8; internal];
    otbake_formats::tree::fill_internal_max(&codes, d, &mut nodes);
    assert!(forge(true, &codes, &nodes).is_ok());
    assert!(forge(false, &[], &[]).is_ok());
    let refused = |stored: bool, s: &[u8], ns: &[u8]| match forge(stored, s, ns) {
        Err(FormatError::Inconsistent { field }) => field,
        other => panic!("expected a refusal, got {other:?}"),
    };
    assert_eq!(refused(true, &codes[..36], &nodes), "spacings");
    assert_eq!(refused(true, &[], &[]), "spacings");
    assert_eq!(refused(false, &codes, &nodes), "spacings");
    assert_eq!(refused(true, &codes, &[]), "node_spacings");
    assert_eq!(refused(false, &[], &nodes), "node_spacings");
    assert_eq!(
        refused(true, &codes, &nodes[..internal - 1]),
        "node_spacings"
    );
    // A point above its leaf's parent's bound, and a node above its parent's.
    let mut high = codes.clone();
    high[20] = 255;
    assert_eq!(refused(true, &high, &nodes), "node_spacings");
    let mut low = nodes.clone();
    low[0] -= 1;
    assert_eq!(refused(true, &codes, &low), "node_spacings");
    // Full storage with no spacings in the content stores none; compact stores none either way.
    let none =
        aligned_copy(&encode_map_content(&content(&pos, &colors, d), Storage::FULL).unwrap());
    assert!(!MapView::open(&none).unwrap().has_spacings());
    let compact = aligned_copy(
        &encode_map_content(
            &MapContent {
                spacings: &spacings,
                ..content(&pos, &colors, d)
            },
            Storage::COMPACT,
        )
        .unwrap(),
    );
    assert!(!MapView::open(&compact).unwrap().has_spacings());
}
