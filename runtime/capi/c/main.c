/* The C test of otbake's C ABI: `otbake_c_test EXPECTED PROXY MAP OTHER_MAP BRDF_PROXY BRDF_MAP`.
 *
 * EXPECTED is the file examples/c_expected.rs writes with the Rust runtime's answers (checked here
 * bit for bit through the C ABI, the prepared records by prepared.c); PROXY and MAP are archives of one bake, OTHER_MAP a map of a
 * bake with another proxy, BRDF_PROXY and BRDF_MAP archives of a BRDF bake (the bad-input half). runtime/capi/ci.sh bakes them, builds this test
 * with `cc` (once plain, once with -fsanitize=address,undefined) and runs it. Exit 0 when every
 * check passed. */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "check.h"

int failures = 0;

File read_file(const char *path) {
  FILE *f = fopen(path, "rb");
  if (!f) {
    fprintf(stderr, "cannot open %s\n", path);
    exit(2);
  }
  fseek(f, 0, SEEK_END);
  long len = ftell(f);
  fseek(f, 0, SEEK_SET);
  /* aligned_alloc wants a multiple of the alignment; the archive is the first `len` bytes. */
  size_t cap = ((size_t)len + 15) / 16 * 16;
  File file = {aligned_alloc(16, cap ? cap : 16), (size_t)len};
  if (!file.bytes || fread(file.bytes, 1, file.len, f) != file.len) {
    fprintf(stderr, "cannot read %s\n", path);
    exit(2);
  }
  fclose(f);
  return file;
}

int main(int argc, char **argv) {
  if (argc != 7) {
    fprintf(stderr, "usage: %s EXPECTED PROXY MAP OTHER_MAP BRDF_PROXY BRDF_MAP\n", argv[0]);
    return 2;
  }
  if (otbake_abi_version() != OTBAKE_ABI_VERSION) {
    fprintf(stderr, "header ABI %d, library ABI %u: rebuild against one otbake\n", OTBAKE_ABI_VERSION,
            otbake_abi_version());
    return 1;
  }
  check_expected(argv[1]);
  check_bad_input(argv[2], argv[3], argv[4], argv[5], argv[6]);
  if (failures) {
    fprintf(stderr, "%d checks failed\n", failures);
    return 1;
  }
  printf("C test passed\n");
  return 0;
}
