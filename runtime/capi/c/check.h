/* Helpers shared by the C test's parts (expected.c and prepared.c: answers bit for bit against the
 * Rust runtime; bad_input.c: refusals, never a crash). */
#ifndef OTBAKE_CHECK_H
#define OTBAKE_CHECK_H

#include <stddef.h>
#include <stdint.h>
#include <stdio.h>

#include "otbake.h"

/* An archive file read into 16-byte aligned memory (what otbake_*_open needs). */
typedef struct {
  uint8_t *bytes;
  size_t len;
} File;

/* Reads `path` whole; exits with a message naming it when it cannot. */
File read_file(const char *path);

/* Counts a failed check (and prints what failed and where); the test fails if any did. */
extern int failures;

#define CHECK(cond, ...)                                                                    \
  do {                                                                                      \
    if (!(cond)) {                                                                          \
      failures++;                                                                           \
      fprintf(stderr, "%s:%d: check failed: %s: ", __FILE__, __LINE__, #cond);              \
      fprintf(stderr, __VA_ARGS__);                                                         \
      fprintf(stderr, "\n");                                                                \
    }                                                                                       \
  } while (0)

/* Checks that `call` returned `expected`, printing both codes' messages and the last error. */
#define CHECK_STATUS(call, expected)                                                        \
  do {                                                                                      \
    OtbakeStatus got_ = (call);                                                             \
    CHECK(got_ == (expected), "%s returned %d (%s), expected %d (%s); last error: %s", #call, \
          (int)got_, otbake_status_message(got_), (int)(expected),                          \
          otbake_status_message(expected), otbake_last_error());                            \
  } while (0)

/* Bits of a float, the float of 8 hex digits, and a bit-for-bit comparison of `n` floats that
 * names `what` and the record line on a mismatch (expected.c). */
uint32_t bits(float x);
float f32_of(const char *hex);
void same_f32(const float *got, const float *want, size_t n, const char *what, int line);
/* A point value as 5 floats: density, mass, color. */
void point_value(const OtbakePointValue *v, float out[5]);

/* The prepared records (prepared.c): the `prepared` line `t[0..nt]` of the blend `blend` (opened
 * from `files[0..nfiles]`, proxy first) at weights `w[0..k]`, then the records up to `pend`, read
 * from `f` (`*line` counts the lines). Returns the number of records checked. */
size_t check_prepared(const OtbakeBlend *blend, const File *files, size_t nfiles, const float *w, size_t k,
                      char **t, size_t nt, FILE *f, int *line);

/* Runs the bit-for-bit half against the records of `expected_path`. */
void check_expected(const char *expected_path);

/* Runs the bad-input half: `proxy`, `map` and `other_map` (a map of another proxy) are paths of
 * 2D archives, `brdf_proxy` and `brdf_map` of a BRDF bake. */
void check_bad_input(const char *proxy, const char *map, const char *other_map, const char *brdf_proxy,
                     const char *brdf_map);

#endif
