/* The bad-input half of the C test: null pointers, misaligned pointers and bytes, truncated and
 * corrupt bytes, wrong counts, overlapping buffers, foreign handles and maps of another proxy each
 * give their status code (and a last-error text naming the argument), never a crash. */
#include <math.h>
#include <pthread.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "check.h"

/* The last error names `needle` (the argument, the element, the runtime's reason). */
#define CHECK_MESSAGE(needle)                                                               \
  CHECK(strstr(otbake_last_error(), (needle)) != NULL, "last error `%s` does not mention `%s`", \
        otbake_last_error(), (needle))

static void messages(void) {
  for (int code = 0; code < OTBAKE_STATUS_COUNT; code++) {
    const char *m = otbake_status_message(code);
    CHECK(m != NULL && m[0] != '\0', "status %d has no message", code);
  }
  CHECK(strstr(otbake_status_message(-1), "unknown") != NULL, "code -1: %s", otbake_status_message(-1));
  CHECK(strstr(otbake_status_message(OTBAKE_STATUS_COUNT), "unknown") != NULL, "code past the end");
  char version[32];
  snprintf(version, sizeof version, "%d.%d.%d", OTBAKE_VERSION_MAJOR, OTBAKE_VERSION_MINOR, OTBAKE_VERSION_PATCH);
  CHECK(!strcmp(version, otbake_version()), "header version %s, library %s", version, otbake_version());
}

/* Opening: every refusal leaves *out null. */
static void opening(File proxy, File map) {
  OtbakeProxy *p = (OtbakeProxy *)&p; /* not null: the failed open must clear it */
  CHECK_STATUS(otbake_proxy_open(NULL, proxy.len, &p), OTBAKE_STATUS_NULL_POINTER);
  CHECK(p == NULL, "a failed open left *out set");
  CHECK_MESSAGE("bytes");
  CHECK_STATUS(otbake_proxy_open(proxy.bytes, proxy.len, NULL), OTBAKE_STATUS_NULL_POINTER);
  CHECK_STATUS(otbake_proxy_open(proxy.bytes, 0, &p), OTBAKE_STATUS_TRUNCATED);
  CHECK_STATUS(otbake_proxy_open(proxy.bytes, 63, &p), OTBAKE_STATUS_TRUNCATED);
  CHECK_STATUS(otbake_proxy_open(proxy.bytes, proxy.len - 1, &p), OTBAKE_STATUS_TRUNCATED);
  CHECK_STATUS(otbake_map_open(map.bytes, map.len / 2, (OtbakeMap **)&p), OTBAKE_STATUS_TRUNCATED);
  /* Misaligned: the same bytes one past a 16-byte boundary. */
  uint8_t *shifted = aligned_alloc(16, (proxy.len + 16 + 15) / 16 * 16);
  memcpy(shifted + 1, proxy.bytes, proxy.len);
  CHECK_STATUS(otbake_proxy_open(shifted + 1, proxy.len, &p), OTBAKE_STATUS_MISALIGNED);
  /* Corrupt: one payload byte flipped (the checksum catches it). */
  memcpy(shifted, proxy.bytes, proxy.len);
  shifted[proxy.len - 5] ^= 0x40;
  CHECK_STATUS(otbake_proxy_open(shifted, proxy.len, &p), OTBAKE_STATUS_CORRUPT);
  /* Not an archive, and archives of the other kind. */
  memset(shifted, 0, proxy.len);
  CHECK_STATUS(otbake_proxy_open(shifted, proxy.len, &p), OTBAKE_STATUS_NOT_ARCHIVE);
  free(shifted);
  OtbakeMap *m = NULL;
  CHECK_STATUS(otbake_map_open(proxy.bytes, proxy.len, &m), OTBAKE_STATUS_NOT_ARCHIVE);
  CHECK_STATUS(otbake_proxy_open(map.bytes, map.len, &p), OTBAKE_STATUS_NOT_ARCHIVE);
  CHECK(p == NULL && m == NULL, "failed opens left handles");
}

/* Making blends: counts, null entries, foreign handles, maps of another proxy. */
static OtbakeBlend *making(OtbakeProxy *proxy, OtbakeMap *map, OtbakeMap *other) {
  OtbakeBlend *b = NULL;
  const OtbakeMap *maps[65];
  for (int i = 0; i < 65; i++) maps[i] = map;
  CHECK_STATUS(otbake_blend_new(NULL, maps, 1, &b), OTBAKE_STATUS_NULL_POINTER);
  CHECK_STATUS(otbake_blend_new(proxy, NULL, 1, &b), OTBAKE_STATUS_NULL_POINTER);
  CHECK_STATUS(otbake_blend_new(proxy, maps, 0, &b), OTBAKE_STATUS_BAD_COUNT);
  CHECK_STATUS(otbake_blend_new(proxy, maps, 65, &b), OTBAKE_STATUS_BAD_COUNT);
  CHECK_MESSAGE("`k`");
  const OtbakeMap *with_null[2] = {map, NULL};
  CHECK_STATUS(otbake_blend_new(proxy, with_null, 2, &b), OTBAKE_STATUS_NULL_POINTER);
  const OtbakeMap *with_proxy[2] = {map, (const OtbakeMap *)proxy};
  CHECK_STATUS(otbake_blend_new(proxy, with_proxy, 2, &b), OTBAKE_STATUS_BAD_HANDLE);
  const OtbakeMap *mixed[2] = {map, other};
  CHECK_STATUS(otbake_blend_new(proxy, mixed, 2, &b), OTBAKE_STATUS_PROXY_MISMATCH);
  CHECK_MESSAGE("map 1");
  CHECK(b == NULL, "a refused blend left *out set");
  OtbakeBrdf *brdf = NULL;
  CHECK_STATUS(otbake_brdf_new_adaptive(proxy, maps, 1, otbake_brdf_default_kernel(), &brdf), OTBAKE_STATUS_NOT_BRDF);
  CHECK_STATUS(otbake_blend_new(proxy, maps, 2, &b), OTBAKE_STATUS_OK);
  /* Handles of the wrong kind are refused, never read as another type. */
  OtbakeBlendInfo info;
  CHECK_STATUS(otbake_blend_info((const OtbakeBlend *)map, &info), OTBAKE_STATUS_BAD_HANDLE);
  CHECK_STATUS(otbake_brdf_info((const OtbakeBrdf *)b, &info), OTBAKE_STATUS_BAD_HANDLE);
  CHECK_STATUS(otbake_blend_info(b, NULL), OTBAKE_STATUS_NULL_POINTER);
  CHECK_STATUS(otbake_blend_info((const OtbakeBlend *)((char *)b + 1), &info), OTBAKE_STATUS_MISALIGNED);
  otbake_blend_free((OtbakeBlend *)map); /* another kind: ignored */
  otbake_blend_free(NULL);
  return b;
}

/* Queries: weights, coordinates, kernels, counts, pointers, overlap, batch failures. */
static void querying(const OtbakeBlend *b) {
  OtbakeBlendInfo info;
  CHECK_STATUS(otbake_blend_info(b, &info), OTBAKE_STATUS_OK);
  size_t d = info.dim;
  float w[2] = {0.5f, 0.5f}, p[4] = {0.5f, 0.5f, 0.5f, 0.5f};
  OtbakePointValue v, out[8];
  CHECK_STATUS(otbake_blend_point(b, w, 2, p, d, 0.05f, &v), OTBAKE_STATUS_OK);
  CHECK_STATUS(otbake_blend_point(NULL, w, 2, p, d, 0.05f, &v), OTBAKE_STATUS_NULL_POINTER);
  CHECK_STATUS(otbake_blend_point(b, w, 2, p, d, 0.05f, NULL), OTBAKE_STATUS_NULL_POINTER);
  CHECK_STATUS(otbake_blend_point(b, NULL, 2, p, d, 0.05f, &v), OTBAKE_STATUS_NULL_POINTER);
  CHECK_STATUS(otbake_blend_point(b, w, 1, p, d, 0.05f, &v), OTBAKE_STATUS_BAD_COUNT);
  CHECK_STATUS(otbake_blend_point(b, w, 2, p, d + 1, 0.05f, &v), OTBAKE_STATUS_BAD_COUNT);
  float half[2] = {0.5f, 0.25f}, negative[2] = {1.5f, -0.5f}, nan_w[2] = {NAN, 1.0f};
  CHECK_STATUS(otbake_blend_point(b, half, 2, p, d, 0.05f, &v), OTBAKE_STATUS_BAD_WEIGHTS);
  CHECK_MESSAGE("sum");
  CHECK_STATUS(otbake_blend_point(b, negative, 2, p, d, 0.05f, &v), OTBAKE_STATUS_BAD_WEIGHTS);
  CHECK_STATUS(otbake_blend_point(b, nan_w, 2, p, d, 0.05f, &v), OTBAKE_STATUS_BAD_WEIGHTS);
  float bad_p[4] = {0.5f, NAN, 0.5f, 0.5f};
  CHECK_STATUS(otbake_blend_point(b, w, 2, bad_p, d, 0.05f, &v), OTBAKE_STATUS_BAD_COORDINATE);
  CHECK_STATUS(otbake_blend_point(b, w, 2, p, d, 0.0f, &v), OTBAKE_STATUS_BAD_KERNEL);
  CHECK_STATUS(otbake_blend_point(b, w, 2, p, d, NAN, &v), OTBAKE_STATUS_BAD_KERNEL);
  OtbakeAdaptiveKernel bad_k = {2.0f, 0.1f, 0.01f};
  CHECK_STATUS(otbake_blend_point_adaptive(b, w, 2, p, d, bad_k, &v), OTBAKE_STATUS_BAD_KERNEL);
  /* Misaligned floats: a float array one byte past a float boundary. */
  float storage[16] = {0};
  const float *odd = (const float *)((const char *)storage + 1);
  CHECK_STATUS(otbake_blend_point(b, w, 2, odd, d, 0.05f, &v), OTBAKE_STATUS_MISALIGNED);
  CHECK_MESSAGE("point");
  /* Batches: overflow, stride, overlap, and a refused element in the middle. */
  float pts[8 * 4];
  for (int i = 0; i < 8 * 4; i++) pts[i] = 0.1f * (float)(i % 9);
  CHECK_STATUS(otbake_blend_point_batch(b, w, 2, 0, pts, d, SIZE_MAX / 2, 0.05f, out), OTBAKE_STATUS_BAD_COUNT);
  CHECK_STATUS(otbake_blend_point_batch(b, w, 2, 1, pts, d, 8, 0.05f, out), OTBAKE_STATUS_BAD_COUNT);
  CHECK_MESSAGE("weight_stride");
  CHECK_STATUS(otbake_blend_point_batch(b, w, 2, 0, pts, d + 1, 8, 0.05f, out), OTBAKE_STATUS_BAD_COUNT);
  CHECK_STATUS(otbake_blend_point_batch(b, w, 2, 0, pts, d, 8, 0.05f, NULL), OTBAKE_STATUS_NULL_POINTER);
  CHECK_STATUS(otbake_blend_point_batch(b, w, 2, 0, pts, d, 2, 0.05f, (OtbakePointValue *)pts), OTBAKE_STATUS_OVERLAP);
  CHECK_STATUS(otbake_blend_point_batch(b, w, 2, 0, pts, d, 0, 0.05f, NULL), OTBAKE_STATUS_OK);
  pts[3 * d + 1] = INFINITY;
  CHECK_STATUS(otbake_blend_point_batch(b, w, 2, 0, pts, d, 8, 0.05f, out), OTBAKE_STATUS_BAD_COORDINATE);
  CHECK_MESSAGE("element 3");
  for (size_t i = 0; i < 3; i++) {
    CHECK_STATUS(otbake_blend_point(b, w, 2, pts + i * d, d, 0.05f, &v), OTBAKE_STATUS_OK);
    CHECK(!memcmp(&v, &out[i], sizeof v), "batch element %zu before the refused one differs", i);
  }
  /* Samples, bandwidths, ranges. */
  OtbakeSample s;
  CHECK_STATUS(otbake_blend_sample(b, w, 2, info.n, &s), OTBAKE_STATUS_INDEX_OUT_OF_RANGE);
  CHECK_STATUS(otbake_blend_sample(b, w, 2, info.n - 1, &s), OTBAKE_STATUS_OK);
  uint32_t idx[2] = {0, info.n};
  OtbakeSample ss[2];
  CHECK_STATUS(otbake_blend_sample_batch(b, w, 2, 0, idx, 2, ss), OTBAKE_STATUS_INDEX_OUT_OF_RANGE);
  CHECK_MESSAGE("element 1");
  float sigma;
  CHECK_STATUS(otbake_blend_bandwidth(b, w, 2, 0, bad_k, &sigma), OTBAKE_STATUS_BAD_KERNEL);
  OtbakeRangeValue r;
  CHECK_STATUS(otbake_blend_range(b, w, 2, p, NULL, d, &r), OTBAKE_STATUS_NULL_POINTER);
  CHECK_MESSAGE("hi");
  CHECK_STATUS(otbake_blend_range(b, w, 2, p, bad_p, d, &r), OTBAKE_STATUS_BAD_COORDINATE);
  float mm;
  CHECK_STATUS(otbake_blend_mean_mass(b, half, 2, &mm), OTBAKE_STATUS_BAD_WEIGHTS);
}

/* Splats: size queries, lengths, regions, overlap. */
static void splatting(const OtbakeBlend *b) {
  float w[2] = {0.5f, 0.5f};
  uint32_t res[2] = {8, 4}, zero[2] = {8, 0};
  size_t cells = 0;
  CHECK_STATUS(otbake_blend_grid_cells(b, res, 2, &cells), OTBAKE_STATUS_OK);
  CHECK(cells == 32, "8x4 grid has %zu cells", cells);
  CHECK_STATUS(otbake_blend_grid_cells(b, zero, 2, &cells), OTBAKE_STATUS_BAD_REGION);
  CHECK_STATUS(otbake_blend_grid_cells(b, res, 3, &cells), OTBAKE_STATUS_BAD_COUNT);
  float density[32] = {0}, color[96] = {0}, rgba[4 * 32] = {0};
  CHECK_STATUS(otbake_blend_splat(b, w, 2, 0.05f, res, 2, density, 32, color, 96), OTBAKE_STATUS_OK);
  CHECK_STATUS(otbake_blend_splat(b, w, 2, 0.05f, res, 2, NULL, 32, color, 96), OTBAKE_STATUS_NULL_POINTER);
  CHECK_STATUS(otbake_blend_splat(b, w, 2, 0.05f, res, 2, density, 31, color, 96), OTBAKE_STATUS_BAD_COUNT);
  CHECK_STATUS(otbake_blend_splat(b, w, 2, 0.05f, res, 2, density, 32, color, 95), OTBAKE_STATUS_BAD_COUNT);
  CHECK_STATUS(otbake_blend_splat(b, w, 2, 0.05f, res, 2, density, 32, density + 4, 3), OTBAKE_STATUS_OVERLAP);
  CHECK_STATUS(otbake_blend_splat(b, w, 2, 0.05f, res, 2, density, 32, NULL, 0), OTBAKE_STATUS_OK);
  OtbakeRegion region = {{8, 4, 1, 1}, {0, 2, 0, 0}, {8, 2, 1, 1}};
  CHECK_STATUS(otbake_blend_region_cells(b, region, &cells), OTBAKE_STATUS_OK);
  CHECK(cells == 16, "region has %zu cells", cells);
  CHECK_STATUS(otbake_blend_splat_region_rgba(b, w, 2, 0.05f, region, rgba, 4 * 16), OTBAKE_STATUS_OK);
  CHECK_STATUS(otbake_blend_splat_region_rgba(b, w, 2, 0.05f, region, rgba, 4 * 16 - 1), OTBAKE_STATUS_BAD_COUNT);
  region.size[1] = 3; /* rows 2..5 of a 4-row grid */
  CHECK_STATUS(otbake_blend_region_cells(b, region, &cells), OTBAKE_STATUS_BAD_REGION);
  CHECK_STATUS(otbake_blend_splat_region_rgba(b, w, 2, 0.05f, region, rgba, 4 * 24), OTBAKE_STATUS_BAD_REGION);
  CHECK_MESSAGE("axis 1");
}

/* Prepared blends: the size query, making one over a caller buffer (null, short, misaligned,
 * overlapping), and its queries (handles, counts, coordinates, kernels, indices, regions, outputs
 * inside the buffer). */
static void preparing(const OtbakeBlend *b) {
  float w[2] = {0.5f, 0.5f}, half[2] = {0.5f, 0.25f}, p[2] = {0.5f, 0.5f};
  OtbakePreparedSizes sizes;
  CHECK_STATUS(otbake_blend_prepared_sizes(NULL, &sizes), OTBAKE_STATUS_NULL_POINTER);
  CHECK_STATUS(otbake_blend_prepared_sizes(b, NULL), OTBAKE_STATUS_NULL_POINTER);
  CHECK_STATUS(otbake_blend_prepared_sizes(b, &sizes), OTBAKE_STATUS_OK);
  size_t total = sizes.total;
  CHECK(total > 0 && sizes.positions > 0, "a blend needs a buffer");
  /* One spare float in front, so that the buffer can also be given one byte off. */
  float *store = malloc((total + 2) * sizeof(float)), *buf = store + 1;
  OtbakePrepared *pr = (OtbakePrepared *)&pr; /* not null: every refusal must clear it */
  CHECK_STATUS(otbake_prepared_new(b, w, 2, NULL, total, NULL, NULL, &pr), OTBAKE_STATUS_NULL_POINTER);
  CHECK(pr == NULL, "a refused prepare left *out set");
  CHECK_MESSAGE("buffer");
  CHECK_STATUS(otbake_prepared_new(b, w, 2, buf, total - 1, NULL, NULL, &pr), OTBAKE_STATUS_BAD_COUNT);
  CHECK_MESSAGE("buffer_len");
  CHECK_STATUS(otbake_prepared_new(b, w, 2, buf, 0, NULL, NULL, &pr), OTBAKE_STATUS_BAD_COUNT);
  CHECK_STATUS(otbake_prepared_new(b, w, 2, (float *)((char *)buf + 1), total, NULL, NULL, &pr),
               OTBAKE_STATUS_MISALIGNED);
  CHECK_STATUS(otbake_prepared_new(b, w, 1, buf, total, NULL, NULL, &pr), OTBAKE_STATUS_BAD_COUNT);
  CHECK_STATUS(otbake_prepared_new(b, half, 2, buf, total, NULL, NULL, &pr), OTBAKE_STATUS_BAD_WEIGHTS);
  CHECK_STATUS(otbake_prepared_new(b, NULL, 2, buf, total, NULL, NULL, &pr), OTBAKE_STATUS_NULL_POINTER);
  CHECK_STATUS(otbake_prepared_new(NULL, w, 2, buf, total, NULL, NULL, &pr), OTBAKE_STATUS_NULL_POINTER);
  CHECK_STATUS(otbake_prepared_new((const OtbakeBlend *)&sizes, w, 2, buf, total, NULL, NULL, &pr),
               OTBAKE_STATUS_BAD_HANDLE);
  CHECK_STATUS(otbake_prepared_new(b, w, 2, buf, total, NULL, NULL, NULL), OTBAKE_STATUS_NULL_POINTER);
  /* Weights inside the buffer, and the handle pointer inside it. */
  buf[3] = 0.5f;
  buf[4] = 0.5f;
  CHECK_STATUS(otbake_prepared_new(b, buf + 3, 2, buf, total, NULL, NULL, &pr), OTBAKE_STATUS_OVERLAP);
  CHECK_MESSAGE("buffer");
  CHECK_STATUS(otbake_prepared_new(b, w, 2, buf, total, NULL, NULL, (OtbakePrepared **)(buf + 8)),
               OTBAKE_STATUS_OVERLAP);
  CHECK(pr == NULL, "refused prepares left *out set");
  CHECK_STATUS(otbake_prepared_new(b, w, 2, buf, total, NULL, NULL, &pr), OTBAKE_STATUS_OK);
  if (!pr) {
    free(store);
    return;
  }

  /* Handles of the wrong kind, both ways. */
  OtbakePointValue v, vs[8];
  OtbakePreparedInfo info;
  OtbakeBlendInfo binfo;
  CHECK_STATUS(otbake_prepared_info((const OtbakePrepared *)b, &info), OTBAKE_STATUS_BAD_HANDLE);
  CHECK_STATUS(otbake_blend_info((const OtbakeBlend *)pr, &binfo), OTBAKE_STATUS_BAD_HANDLE);
  CHECK_STATUS(otbake_prepared_point(NULL, p, 2, 0.05f, &v), OTBAKE_STATUS_NULL_POINTER);
  CHECK_STATUS(otbake_prepared_point((const OtbakePrepared *)((char *)pr + 1), p, 2, 0.05f, &v),
               OTBAKE_STATUS_MISALIGNED);
  CHECK_STATUS(otbake_prepared_info(pr, &info), OTBAKE_STATUS_OK);
  CHECK_STATUS(otbake_blend_info(b, &binfo), OTBAKE_STATUS_OK);
  CHECK(info.dim == binfo.dim && info.n == binfo.n && info.has_color == binfo.has_color, "prepared info: dim %u",
        info.dim);
  CHECK_STATUS(otbake_prepared_info(pr, (OtbakePreparedInfo *)(buf + 2)), OTBAKE_STATUS_OVERLAP);
  /* Points: counts, coordinates, kernels, outputs. */
  float bad_p[2] = {0.5f, NAN};
  CHECK_STATUS(otbake_prepared_point(pr, p, 3, 0.05f, &v), OTBAKE_STATUS_BAD_COUNT);
  CHECK_STATUS(otbake_prepared_point(pr, bad_p, 2, 0.05f, &v), OTBAKE_STATUS_BAD_COORDINATE);
  CHECK_STATUS(otbake_prepared_point(pr, p, 2, -1.0f, &v), OTBAKE_STATUS_BAD_KERNEL);
  CHECK_STATUS(otbake_prepared_point(pr, p, 2, 0.05f, NULL), OTBAKE_STATUS_NULL_POINTER);
  CHECK_STATUS(otbake_prepared_point(pr, p, 2, 0.05f, (OtbakePointValue *)buf), OTBAKE_STATUS_OVERLAP);
  CHECK_MESSAGE("prepared blend's buffer");
  /* Inputs may lie in the buffer (its own positions, say). */
  const float *positions = NULL;
  size_t plen = 0;
  CHECK_STATUS(otbake_prepared_positions(pr, &positions, &plen), OTBAKE_STATUS_OK);
  CHECK_STATUS(otbake_prepared_positions(pr, NULL, &plen), OTBAKE_STATUS_NULL_POINTER);
  CHECK_STATUS(otbake_prepared_point(pr, positions, 2, 0.05f, &v), OTBAKE_STATUS_OK);
  CHECK(v.density > 0.0f, "a query at a point of the blend sees it");
  float pts[8 * 2];
  for (int i = 0; i < 16; i++) pts[i] = 0.1f * (float)(i % 9);
  CHECK_STATUS(otbake_prepared_point_batch(pr, pts, 2, 8, 0.05f, vs), OTBAKE_STATUS_OK);
  CHECK_STATUS(otbake_prepared_point_batch(pr, pts, 3, 8, 0.05f, vs), OTBAKE_STATUS_BAD_COUNT);
  CHECK_STATUS(otbake_prepared_point_batch(pr, pts, 2, SIZE_MAX / 2, 0.05f, vs), OTBAKE_STATUS_BAD_COUNT);
  CHECK_STATUS(otbake_prepared_point_batch(pr, pts, 2, 8, 0.05f, NULL), OTBAKE_STATUS_NULL_POINTER);
  CHECK_STATUS(otbake_prepared_point_batch(pr, pts, 2, 2, 0.05f, (OtbakePointValue *)pts), OTBAKE_STATUS_OVERLAP);
  CHECK_STATUS(otbake_prepared_point_batch(pr, pts, 2, 2, 0.05f, (OtbakePointValue *)(buf + total - 3)),
               OTBAKE_STATUS_OVERLAP);
  CHECK_STATUS(otbake_prepared_point_batch(pr, pts, 2, 0, 0.05f, NULL), OTBAKE_STATUS_OK);
  pts[2 * 5] = INFINITY;
  CHECK_STATUS(otbake_prepared_point_batch(pr, pts, 2, 8, 0.05f, vs), OTBAKE_STATUS_BAD_COORDINATE);
  CHECK_MESSAGE("element 5");
  /* Ranges and samples. */
  OtbakeRangeValue r;
  CHECK_STATUS(otbake_prepared_range(pr, p, NULL, 2, &r), OTBAKE_STATUS_NULL_POINTER);
  CHECK_MESSAGE("hi");
  CHECK_STATUS(otbake_prepared_range(pr, p, bad_p, 2, &r), OTBAKE_STATUS_BAD_COORDINATE);
  CHECK_STATUS(otbake_prepared_range(pr, p, p, 1, &r), OTBAKE_STATUS_BAD_COUNT);
  OtbakeRangeValue rs[2];
  CHECK_STATUS(otbake_prepared_range_batch(pr, pts, pts, 3, 2, rs), OTBAKE_STATUS_BAD_COUNT);
  CHECK_STATUS(otbake_prepared_range_batch(pr, pts, pts, 2, 2, (OtbakeRangeValue *)pts), OTBAKE_STATUS_OVERLAP);
  OtbakeSample smp, ss[2];
  CHECK_STATUS(otbake_prepared_sample(pr, info.n, &smp), OTBAKE_STATUS_INDEX_OUT_OF_RANGE);
  CHECK_STATUS(otbake_prepared_sample(pr, info.n - 1, &smp), OTBAKE_STATUS_OK);
  uint32_t idx[2] = {0, info.n};
  CHECK_STATUS(otbake_prepared_sample_batch(pr, idx, 2, ss), OTBAKE_STATUS_INDEX_OUT_OF_RANGE);
  CHECK_MESSAGE("element 1");
  CHECK_STATUS(otbake_prepared_sample_batch(pr, NULL, 2, ss), OTBAKE_STATUS_NULL_POINTER);
  CHECK_MESSAGE("indices");
  /* Splats and point grids: size queries, lengths, regions, outputs. */
  uint32_t res[2] = {8, 4}, zero[2] = {8, 0};
  size_t cells = 0;
  CHECK_STATUS(otbake_prepared_grid_cells(pr, res, 2, &cells), OTBAKE_STATUS_OK);
  CHECK(cells == 32, "8x4 grid has %zu cells", cells);
  CHECK_STATUS(otbake_prepared_grid_cells(pr, zero, 2, &cells), OTBAKE_STATUS_BAD_REGION);
  CHECK_STATUS(otbake_prepared_grid_cells(pr, res, 1, &cells), OTBAKE_STATUS_BAD_COUNT);
  CHECK_STATUS(otbake_prepared_grid_cells(pr, res, 2, (size_t *)buf), OTBAKE_STATUS_OVERLAP);
  float density[32] = {0}, color[96] = {0}, rgba[4 * 32] = {0};
  CHECK_STATUS(otbake_prepared_splat(pr, 0.05f, res, 2, density, 32, color, 96), OTBAKE_STATUS_OK);
  CHECK_STATUS(otbake_prepared_splat(pr, 0.05f, res, 2, NULL, 32, color, 96), OTBAKE_STATUS_NULL_POINTER);
  CHECK_STATUS(otbake_prepared_splat(pr, 0.05f, res, 2, density, 31, NULL, 0), OTBAKE_STATUS_BAD_COUNT);
  CHECK_STATUS(otbake_prepared_splat(pr, 0.05f, res, 2, density, 32, color, 95), OTBAKE_STATUS_BAD_COUNT);
  CHECK_STATUS(otbake_prepared_splat(pr, 0.05f, res, 2, density, 32, density + 4, 3), OTBAKE_STATUS_OVERLAP);
  CHECK_STATUS(otbake_prepared_splat(pr, 0.05f, res, 2, buf, 32, NULL, 0), OTBAKE_STATUS_OVERLAP);
  CHECK_STATUS(otbake_prepared_splat(pr, NAN, res, 2, density, 32, NULL, 0), OTBAKE_STATUS_BAD_KERNEL);
  OtbakeRegion region = {{8, 4, 1, 1}, {0, 2, 0, 0}, {8, 2, 1, 1}};
  CHECK_STATUS(otbake_prepared_region_cells(pr, region, &cells), OTBAKE_STATUS_OK);
  CHECK(cells == 16, "region has %zu cells", cells);
  CHECK_STATUS(otbake_prepared_splat_region(pr, 0.05f, region, density, 16, color, 48), OTBAKE_STATUS_OK);
  CHECK_STATUS(otbake_prepared_splat_region(pr, 0.05f, region, density, 15, color, 48), OTBAKE_STATUS_BAD_COUNT);
  CHECK_STATUS(otbake_prepared_splat_region(pr, 0.05f, region, density, 16, buf + 1, 48), OTBAKE_STATUS_OVERLAP);
  CHECK_STATUS(otbake_prepared_splat_region_rgba(pr, 0.05f, region, rgba, 4 * 16), OTBAKE_STATUS_OK);
  CHECK_STATUS(otbake_prepared_splat_region_rgba(pr, 0.05f, region, rgba, 4 * 16 + 1), OTBAKE_STATUS_BAD_COUNT);
  CHECK_STATUS(otbake_prepared_splat_region_rgba(pr, 0.05f, region, NULL, 4 * 16), OTBAKE_STATUS_NULL_POINTER);
  CHECK_STATUS(otbake_prepared_splat_region_rgba(pr, 0.05f, region, (float *)((char *)rgba + 2), 4 * 16),
               OTBAKE_STATUS_MISALIGNED);
  OtbakePointValue grid[16];
  CHECK_STATUS(otbake_prepared_point_grid(pr, 0.05f, region, grid, 16), OTBAKE_STATUS_OK);
  CHECK_STATUS(otbake_prepared_point_grid(pr, 0.05f, region, grid, 15), OTBAKE_STATUS_BAD_COUNT);
  CHECK_STATUS(otbake_prepared_point_grid(pr, 0.05f, region, NULL, 16), OTBAKE_STATUS_NULL_POINTER);
  CHECK_STATUS(otbake_prepared_point_grid(pr, 0.05f, region, (OtbakePointValue *)buf, 16), OTBAKE_STATUS_OVERLAP);
  CHECK_STATUS(otbake_prepared_point_grid(pr, 0.0f, region, grid, 16), OTBAKE_STATUS_BAD_KERNEL);
  region.size[1] = 3; /* rows 2..5 of a 4-row grid */
  CHECK_STATUS(otbake_prepared_region_cells(pr, region, &cells), OTBAKE_STATUS_BAD_REGION);
  CHECK_STATUS(otbake_prepared_point_grid(pr, 0.05f, region, grid, 16), OTBAKE_STATUS_BAD_REGION);
  CHECK_MESSAGE("axis 1");
  /* Refusals wrote nothing into the buffer: the handle still answers as before. */
  OtbakePointValue again;
  CHECK_STATUS(otbake_prepared_point(pr, positions, 2, 0.05f, &again), OTBAKE_STATUS_OK);
  CHECK(!memcmp(&v, &again, sizeof v), "a refused call changed the prepared blend");
  otbake_prepared_free((OtbakePrepared *)b); /* another kind: ignored */
  otbake_prepared_free(NULL);
  otbake_prepared_free(pr);
  free(store);
}

/* The last error is per thread: another thread sees its own (empty) text. */
static void *other_thread(void *arg) {
  (void)arg;
  return (void *)(otbake_last_error()[0] == '\0' ? "empty" : otbake_last_error());
}

static void threads(void) {
  CHECK_STATUS(otbake_proxy_open(NULL, 1, NULL), OTBAKE_STATUS_NULL_POINTER);
  pthread_t t;
  void *seen = NULL;
  CHECK(pthread_create(&t, NULL, other_thread, NULL) == 0, "pthread_create");
  pthread_join(t, &seen);
  CHECK(!strcmp((const char *)seen, "empty"), "another thread saw `%s`", (const char *)seen);
  CHECK(otbake_last_error()[0] != '\0', "this thread lost its error");
}

/* BRDF blends: kernels, directions, random numbers, pointers. */
static void brdf_arguments(File proxy, File map) {
  OtbakeProxy *p = NULL;
  OtbakeMap *m = NULL;
  OtbakeBrdf *b = NULL;
  CHECK_STATUS(otbake_proxy_open(proxy.bytes, proxy.len, &p), OTBAKE_STATUS_OK);
  CHECK_STATUS(otbake_map_open(map.bytes, map.len, &m), OTBAKE_STATUS_OK);
  const OtbakeMap *maps[1] = {m};
  OtbakeAdaptiveKernel bad = {-1.0f, 0.001f, 0.01f};
  CHECK_STATUS(otbake_brdf_new_adaptive(p, maps, 1, bad, &b), OTBAKE_STATUS_BAD_KERNEL);
  CHECK_STATUS(otbake_brdf_new_fixed(p, maps, 1, -0.5f, &b), OTBAKE_STATUS_BAD_KERNEL);
  CHECK_STATUS(otbake_brdf_new_adaptive(p, maps, 1, otbake_brdf_default_kernel(), &b), OTBAKE_STATUS_OK);
  double dirs[8] = {0, 0, 0.6, 0.8, 0, 0.8, 0.6, 0}, xi[6] = {0.1, 0.7, 0.3, 0.4, 0.5, 0};
  const double *wi = dirs + 1, *wo = dirs + 4;
  const double *odd = (const double *)((const char *)dirs + 4);
  float w[1] = {1.0f}, w2[2] = {0.5f, 0.5f}, rgb[3];
  double pdf;
  OtbakeBrdfSample s;
  CHECK_STATUS(otbake_brdf_eval(b, w, 1, wi, wo, rgb), OTBAKE_STATUS_OK);
  CHECK_STATUS(otbake_brdf_eval(NULL, w, 1, wi, wo, rgb), OTBAKE_STATUS_NULL_POINTER);
  CHECK_STATUS(otbake_brdf_eval(b, w, 1, NULL, wo, rgb), OTBAKE_STATUS_NULL_POINTER);
  CHECK_MESSAGE("wi");
  CHECK_STATUS(otbake_brdf_eval(b, w, 1, odd, wo, rgb), OTBAKE_STATUS_MISALIGNED);
  CHECK_STATUS(otbake_brdf_eval(b, w2, 2, wi, wo, rgb), OTBAKE_STATUS_BAD_COUNT);
  CHECK_STATUS(otbake_brdf_pdf(b, w, 1, wi, wo, NULL), OTBAKE_STATUS_NULL_POINTER);
  CHECK_STATUS(otbake_brdf_pdf(b, w, 1, wi, wo, (double *)wo), OTBAKE_STATUS_OVERLAP);
  CHECK_STATUS(otbake_brdf_pdf(b, w, 1, wi, wo, &pdf), OTBAKE_STATUS_OK);
  CHECK_STATUS(otbake_brdf_sample(b, w, 1, 0, xi, &s), OTBAKE_STATUS_OK);
  CHECK_STATUS(otbake_brdf_sample(b, w, 1, 1u << 30, xi, &s), OTBAKE_STATUS_INDEX_OUT_OF_RANGE);
  CHECK_STATUS(otbake_brdf_sample(b, w, 1, 0, NULL, &s), OTBAKE_STATUS_NULL_POINTER);
  CHECK_MESSAGE("xi");
  CHECK_STATUS(otbake_brdf_sample_batch(b, w, 1, 0, NULL, xi, 1, &s), OTBAKE_STATUS_NULL_POINTER);
  CHECK_MESSAGE("indices");
  OtbakeBlendInfo info;
  CHECK_STATUS(otbake_blend_info((const OtbakeBlend *)b, &info), OTBAKE_STATUS_BAD_HANDLE);
  otbake_brdf_free(b);
  otbake_brdf_free(NULL);
  otbake_map_free(m);
  otbake_proxy_free(p);
}

void check_bad_input(const char *proxy_path, const char *map_path, const char *other_path,
                     const char *brdf_proxy_path, const char *brdf_map_path) {
  File proxy = read_file(proxy_path), map = read_file(map_path), other = read_file(other_path);
  File brdf_proxy = read_file(brdf_proxy_path), brdf_map = read_file(brdf_map_path);
  messages();
  opening(proxy, map);
  OtbakeProxy *p = NULL;
  OtbakeMap *m = NULL, *o = NULL;
  CHECK_STATUS(otbake_proxy_open(proxy.bytes, proxy.len, &p), OTBAKE_STATUS_OK);
  CHECK_STATUS(otbake_map_open(map.bytes, map.len, &m), OTBAKE_STATUS_OK);
  CHECK_STATUS(otbake_map_open(other.bytes, other.len, &o), OTBAKE_STATUS_OK);
  OtbakeBlend *b = making(p, m, o);
  if (b) {
    querying(b);
    splatting(b);
    preparing(b);
  }
  threads();
  brdf_arguments(brdf_proxy, brdf_map);
  otbake_blend_free(b);
  otbake_map_free(o);
  otbake_map_free(m);
  otbake_proxy_free(p);
  free(proxy.bytes);
  free(map.bytes);
  free(other.bytes);
  free(brdf_proxy.bytes);
  free(brdf_map.bytes);
  printf("bad input: every refusal gave its code\n");
}
