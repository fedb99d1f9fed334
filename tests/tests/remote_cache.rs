//! `otbake bake --remote-cache` against an in-process fake of Bazel's HTTP cache: cold and warm
//! runners, and every way a server can fail (down, 500, garbage, read-only, corrupt blob, slow),
//! none of which may fail a bake or leave anything corrupt. The same scenarios run against real
//! nginx in `remote_nginx.rs`.

mod remote_support;

use otbake_tests::otbake_err;
use remote_support::fake::FakeCache;
use remote_support::{CacheServer, Location};

#[test]
fn a_second_runner_gets_every_product_from_the_cache() {
    remote_support::cold_then_warm(&FakeCache::start(), "rc-fake");
}

#[test]
fn a_server_that_is_down_bakes_locally() {
    remote_support::falls_back(&remote_support::dead_url(), "rc-fake-down", "unreachable");
}

#[test]
fn a_server_failing_with_500_bakes_locally() {
    let s = FakeCache::start();
    remote_support::falls_back(&s.url(Location::Fails), "rc-fake-500", "HTTP status 500");
}

#[test]
fn a_slow_server_times_out_and_bakes_locally() {
    remote_support::slow(&FakeCache::start(), "rc-fake-slow");
}

#[test]
fn garbage_from_the_server_is_never_trusted() {
    remote_support::rejects_garbage(&FakeCache::start(), "rc-fake-garbage");
}

#[test]
fn a_read_only_cache_is_read_and_not_written() {
    remote_support::read_only(&FakeCache::start(), "rc-fake-ro");
}

#[test]
fn a_corrupt_blob_is_detected_rebaked_and_repaired() {
    remote_support::corrupt_blob(&FakeCache::start(), "rc-fake-corrupt");
}

#[test]
fn a_bad_remote_cache_url_is_a_clear_error() {
    let (dir, m) = remote_support::runner("rc-url", 0);
    let m = m.to_str().unwrap();
    for (url, says) in [
        ("https://cache.example:443/", "https is not built in"),
        (
            "grpc://cache.example:9092",
            "give an http://HOST:PORT/ address",
        ),
        ("http:///cas", "no host"),
    ] {
        let err = otbake_err(&dir, &["bake", m, "--remote-cache", url]);
        assert!(err.contains(says) && err.contains(url), "{url}: {err}");
    }
    assert!(!dir.join("out").exists(), "nothing baked on a bad URL");
}
