//! `cargo run --release -p otbake-tests --bin otbake-fuzz -- [ITERATIONS] [SEED]`: a fuzzing campaign
//! over the corpus in tests/fuzz/corpus. Prints executions, archives that still opened after mutation,
//! and findings (inputs that made the runtime panic, written to tests/fuzz/findings/).

use otbake_formats::ArchiveKind;
use otbake_tests::fuzz::{exercise, mutate, Rng};
use std::panic::{catch_unwind, AssertUnwindSafe};

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let iterations: u64 = args.get(1).and_then(|v| v.parse().ok()).unwrap_or(100_000);
    let seed: u64 = args.get(2).and_then(|v| v.parse().ok()).unwrap_or(1);
    let root = otbake_tests::repo_root().join("tests/fuzz");
    let corpus = otbake_tests::fuzz_corpus(&root.join("corpus"));
    std::panic::set_hook(Box::new(|_| {}));
    let mut rng = Rng(seed);
    let (mut opened, mut findings) = (0u64, 0u64);
    let t = std::time::Instant::now();
    for i in 0..iterations {
        let case = &corpus[rng.below(corpus.len())];
        let mut proxy = case.proxy.clone();
        let mut maps = case.maps.clone();
        if rng.below(3) == 0 {
            mutate(&mut rng, &mut proxy, ArchiveKind::Proxy);
        } else {
            let m = rng.below(maps.len());
            mutate(&mut rng, &mut maps[m], ArchiveKind::Map);
        }
        let mut qrng = Rng(rng.next_u64());
        let refs: Vec<&[u8]> = maps.iter().map(|m| m.as_slice()).collect();
        match catch_unwind(AssertUnwindSafe(|| exercise(&mut qrng, &proxy, &refs))) {
            Ok(n) => opened += (n == 2) as u64,
            Err(_) => {
                findings += 1;
                let dir = root.join("findings");
                std::fs::create_dir_all(&dir).unwrap();
                std::fs::write(dir.join(format!("{seed}-{i}-proxy.otb")), &proxy).unwrap();
                for (j, m) in maps.iter().enumerate() {
                    std::fs::write(dir.join(format!("{seed}-{i}-map{j}.otb")), m).unwrap();
                }
            }
        }
    }
    println!(
        "{iterations} executions, seed {seed}: {opened} mutated archive sets still opened and were queried, {findings} findings, {:.1} s",
        t.elapsed().as_secs_f64()
    );
    if findings > 0 {
        std::process::exit(1);
    }
}
