//! The ABI's fixed parts (versions, codes, messages) and its thread-safety promise: one blend (or
//! prepared blend) queried from several threads at once gives every thread the single-threaded
//! answers, and each thread keeps its own last error.

mod common;

use otbake_capi::*;
use std::ffi::CStr;
use std::ptr::null_mut;

#[test]
fn versions_match_the_crate() {
    let v = format!("{OTBAKE_VERSION_MAJOR}.{OTBAKE_VERSION_MINOR}.{OTBAKE_VERSION_PATCH}");
    assert_eq!(
        v,
        env!("CARGO_PKG_VERSION"),
        "update OTBAKE_VERSION_* in src/lib.rs"
    );
    // SAFETY: a static NUL-terminated string.
    let lib = unsafe { CStr::from_ptr(otbake_version()) };
    assert_eq!(lib.to_str().unwrap(), v);
    assert_eq!(otbake_abi_version(), OTBAKE_ABI_VERSION);
}

#[test]
fn every_code_has_its_own_message() {
    let mut seen = std::collections::HashSet::new();
    for code in 0..OTBAKE_STATUS_COUNT {
        // SAFETY: static NUL-terminated strings.
        let m = unsafe { CStr::from_ptr(otbake_status_message(code)) }
            .to_str()
            .unwrap();
        assert!(!m.is_empty() && !m.contains("unknown"), "code {code}: {m}");
        assert!(seen.insert(m.to_owned()), "code {code} repeats `{m}`");
    }
    for code in [-1, OTBAKE_STATUS_COUNT, i32::MAX, i32::MIN] {
        // SAFETY: as above.
        let m = unsafe { CStr::from_ptr(otbake_status_message(code)) };
        assert!(m.to_str().unwrap().contains("unknown"));
    }
    assert_eq!(OtbakeStatus::Internal as i32, OTBAKE_STATUS_COUNT - 1);
}

/// A blend handle that threads may share (the ABI promises it; Rust cannot see it).
#[derive(Clone, Copy)]
struct Shared(*const OtbakeBlend);
// SAFETY: blends are immutable after creation (the property under test).
unsafe impl Send for Shared {}
// SAFETY: as above.
unsafe impl Sync for Shared {}

#[test]
fn threads_share_a_blend_and_keep_their_own_errors() {
    let a = common::archives(5, 600, 2, 3, [9; 32]);
    let mut proxy = null_mut();
    let mut maps = vec![];
    let mut blend = null_mut();
    // SAFETY: the bytes outlive the handles; out pointers are valid.
    unsafe {
        assert_eq!(
            otbake_proxy_open(a.proxy.as_ptr(), a.proxy.len(), &mut proxy),
            OtbakeStatus::Ok
        );
        for m in &a.maps {
            let mut h = null_mut();
            assert_eq!(
                otbake_map_open(m.as_ptr(), m.len(), &mut h),
                OtbakeStatus::Ok
            );
            maps.push(h.cast_const());
        }
        assert_eq!(
            otbake_blend_new(proxy, maps.as_ptr(), 3, &mut blend),
            OtbakeStatus::Ok
        );
        // The blend keeps its own views: the other handles may go now.
        otbake_proxy_free(proxy);
        for m in maps {
            otbake_map_free(m.cast_mut());
        }
    }
    let points: Vec<f32> = (0..2 * 500).map(|i| (i as f32 * 0.123) % 1.0).collect();
    let w = [0.2f32, 0.3, 0.5];
    let run = |b: Shared| {
        let mut out = vec![OtbakePointValue::default(); 500];
        // SAFETY: the blend is live until after the scope; buffers cover the counts.
        let s = unsafe {
            otbake_blend_point_batch(
                b.0,
                w.as_ptr(),
                3,
                0,
                points.as_ptr(),
                2,
                500,
                0.03,
                out.as_mut_ptr(),
            )
        };
        assert_eq!(s, OtbakeStatus::Ok);
        out
    };
    let shared = Shared(blend);
    let alone = run(shared);
    let (run, points) = (&run, &points);
    std::thread::scope(|scope| {
        let handles: Vec<_> = (0..4)
            .map(|t| {
                scope.spawn(move || {
                    let out = run(shared);
                    // Each thread's refusal is its own text.
                    let mut v = OtbakePointValue::default();
                    let k = t + 1; // wrong for t != 2
                                   // SAFETY: as above.
                    let s = unsafe {
                        otbake_blend_point(
                            shared.0,
                            w.as_ptr(),
                            k,
                            points.as_ptr(),
                            2,
                            0.03,
                            &mut v,
                        )
                    };
                    // SAFETY: the thread's NUL-terminated last-error text.
                    let text = unsafe { CStr::from_ptr(otbake_last_error()) }
                        .to_string_lossy()
                        .into_owned();
                    (out, s, text, k)
                })
            })
            .collect();
        for h in handles {
            let (out, s, text, k) = h.join().unwrap();
            assert_eq!(out, alone, "a thread saw other answers");
            if k == 3 {
                assert_eq!(s, OtbakeStatus::Ok);
                assert_eq!(text, "", "a thread saw another thread's error");
            } else {
                assert_eq!(s, OtbakeStatus::BadCount);
                assert!(
                    text.contains(&format!("{k} weights given for 3 maps")),
                    "{text}"
                );
            }
        }
    });
    // SAFETY: no thread uses the blend any more.
    unsafe { otbake_blend_free(blend) };
}

/// A prepared handle that threads may share (immutable, like a blend).
#[derive(Clone, Copy)]
struct SharedPrepared(*const OtbakePrepared);
// SAFETY: prepared handles are immutable after creation (the property under test).
unsafe impl Send for SharedPrepared {}
// SAFETY: as above.
unsafe impl Sync for SharedPrepared {}

#[test]
fn threads_share_a_prepared_blend_with_the_blends_bits() {
    let a = common::archives(6, 600, 2, 2, [5; 32]);
    let (mut proxy, mut blend, mut prepared) = (null_mut(), null_mut(), null_mut());
    let mut maps = vec![];
    let w = [0.3f32, 0.7];
    let mut sizes = OtbakePreparedSizes::default();
    // SAFETY: the bytes outlive the handles; out pointers are valid.
    unsafe {
        assert_eq!(
            otbake_proxy_open(a.proxy.as_ptr(), a.proxy.len(), &mut proxy),
            OtbakeStatus::Ok
        );
        for m in &a.maps {
            let mut h = null_mut();
            assert_eq!(
                otbake_map_open(m.as_ptr(), m.len(), &mut h),
                OtbakeStatus::Ok
            );
            maps.push(h.cast_const());
        }
        assert_eq!(
            otbake_blend_new(proxy, maps.as_ptr(), 2, &mut blend),
            OtbakeStatus::Ok
        );
        assert_eq!(
            otbake_blend_prepared_sizes(blend, &mut sizes),
            OtbakeStatus::Ok
        );
    }
    let mut store = vec![0.0f32; sizes.total];
    // SAFETY: `store` outlives the prepared handle and is not written while it lives.
    unsafe {
        assert_eq!(
            otbake_prepared_new(
                blend,
                w.as_ptr(),
                2,
                store.as_mut_ptr(),
                store.len(),
                None,
                null_mut(),
                &mut prepared,
            ),
            OtbakeStatus::Ok
        );
    }
    let points: Vec<f32> = (0..2 * 400).map(|i| (i as f32 * 0.377) % 1.0).collect();
    let mut from_blend = vec![OtbakePointValue::default(); 400];
    // SAFETY: live blend; buffers cover the counts.
    let s = unsafe {
        otbake_blend_point_batch(
            blend,
            w.as_ptr(),
            2,
            0,
            points.as_ptr(),
            2,
            400,
            0.04,
            from_blend.as_mut_ptr(),
        )
    };
    assert_eq!(s, OtbakeStatus::Ok);
    // The prepared handle reads only its buffer: every other handle may go first.
    // SAFETY: no other call uses these handles.
    unsafe {
        otbake_blend_free(blend);
        otbake_proxy_free(proxy);
        for m in maps {
            otbake_map_free(m.cast_mut());
        }
    }
    let run = |p: SharedPrepared| {
        let mut out = vec![OtbakePointValue::default(); 400];
        // SAFETY: the prepared handle is live until after the scope; buffers cover the counts.
        let s = unsafe {
            otbake_prepared_point_batch(p.0, points.as_ptr(), 2, 400, 0.04, out.as_mut_ptr())
        };
        assert_eq!(s, OtbakeStatus::Ok);
        out
    };
    let shared = SharedPrepared(prepared);
    assert_eq!(
        run(shared),
        from_blend,
        "prepared answers differ from the blend's"
    );
    let run = &run;
    std::thread::scope(|scope| {
        let handles: Vec<_> = (0..4).map(|_| scope.spawn(move || run(shared))).collect();
        for h in handles {
            assert_eq!(h.join().unwrap(), from_blend, "a thread saw other answers");
        }
    });
    // SAFETY: no thread uses the handle any more; the buffer goes after it.
    unsafe { otbake_prepared_free(prepared) };
    drop(store);
}
