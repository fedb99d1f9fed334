//! `otbake bake --remote-cache` against real nginx on 127.0.0.1 (WebDAV PUT), the server a team
//! would run: cold and warm runners, a blob corrupted on the server's disk, a read-only location,
//! 500, garbage, a location that never answers. They need Debian's `nginx-light`, so they are `#[ignore]`d
//! in a plain `cargo test`; `.ci/bazel` installs nginx and runs them with `-- --ignored`.

mod remote_support;

use remote_support::nginx::Nginx;
use remote_support::{CacheServer, Location};

#[test]
#[ignore = "needs nginx-light: run by .ci/bazel"]
fn nginx_a_second_runner_gets_every_product_from_the_cache() {
    remote_support::cold_then_warm(&Nginx::start("rn-cache"), "rn");
}

#[test]
#[ignore = "needs nginx-light: run by .ci/bazel"]
fn nginx_a_corrupt_blob_on_disk_is_detected_rebaked_and_repaired() {
    remote_support::corrupt_blob(&Nginx::start("rn-corrupt-srv"), "rn-corrupt");
}

#[test]
#[ignore = "needs nginx-light: run by .ci/bazel"]
fn nginx_a_read_only_location_is_read_and_not_written() {
    remote_support::read_only(&Nginx::start("rn-ro-srv"), "rn-ro");
}

#[test]
#[ignore = "needs nginx-light: run by .ci/bazel"]
fn nginx_500_garbage_slow_and_down_bake_locally() {
    let s = Nginx::start("rn-faults-srv");
    remote_support::falls_back(&s.url(Location::Fails), "rn-500", "HTTP status 500");
    remote_support::rejects_garbage(&s, "rn-garbage");
    remote_support::slow(&s, "rn-slow");
    let url = s.url(Location::Cache);
    drop(s);
    remote_support::falls_back(&url, "rn-down", "unreachable");
}
