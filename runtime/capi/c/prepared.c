/* The prepared half of the bit-for-bit check: for every `prepared` section of the expected-values
 * file (written by examples/c_expected.rs with the Rust runtime's Blend::prepare and Prepared
 * queries), prepares the blend through the C ABI three ways — alone on a blend made from a copy of
 * the archives that is freed and poisoned before any query, with a join that runs the halves on
 * two threads, and with a join that runs neither — and checks that the buffers are the same bits,
 * then repeats every record (point, range, sample: once and as a batch; point grid, whole-grid,
 * region and RGBA region splats) and compares the bits of every answer. */
#define _POSIX_C_SOURCE 200809L
#include <pthread.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "check.h"

#define MAX_PRECORDS 64

/* FNV-1a (64 bits) over the little-endian bytes of the bits of `n` floats (as c_expected.rs). */
static uint64_t fnv(const float *xs, size_t n) {
  uint64_t hash = 0xcbf29ce484222325ull;
  for (size_t i = 0; i < n; i++) {
    uint32_t u = bits(xs[i]);
    for (int b = 0; b < 4; b++) {
      hash = (hash ^ ((u >> (8 * b)) & 0xff)) * 0x100000001b3ull;
    }
  }
  return hash;
}

/* A join that runs half `a` on a new thread and half `b` on this one (both, in order, if no
 * thread can be made); counts its calls in `*context`. */
typedef struct {
  OtbakeTaskFn run;
  void *task;
} Half;

static void *half_thread(void *arg) {
  Half *h = arg;
  h->run(h->task);
  return NULL;
}

static void two_threads(void *context, OtbakeTaskFn run, void *a, void *b) {
  pthread_t t;
  Half h = {run, a};
  if (pthread_create(&t, NULL, half_thread, &h) != 0) {
    run(a);
    run(b);
  } else {
    run(b);
    pthread_join(t, NULL);
  }
  (*(int *)context)++;
}

/* A join that runs neither half: the library runs them after it returns. */
static void lazy_join(void *context, OtbakeTaskFn run, void *a, void *b) {
  (void)run;
  (void)a;
  (void)b;
  (*(int *)context)++;
}

/* Reads `cells` lines `cell v0 .. v{per-1}` into `want`; false at a short file. */
static int read_cells(FILE *f, int *line, size_t cells, size_t per, float *want) {
  char *text = NULL;
  size_t cap = 0;
  int ok = 1;
  for (size_t c = 0; c < cells && ok; c++) {
    (*line)++;
    if (getline(&text, &cap, f) < 0) {
      CHECK(0, "expected file ends inside a prepared grid");
      ok = 0;
      break;
    }
    char *save = NULL;
    strtok_r(text, " \n", &save);
    for (size_t i = 0; i < per; i++) {
      const char *tok = strtok_r(NULL, " \n", &save);
      want[c * per + i] = tok ? f32_of(tok) : 0.0f;
    }
  }
  free(text);
  return ok;
}

/* A blend made from copies of the archive bytes (aligned like the originals); the copies are
 * returned for the caller to poison and free once the blend is gone. */
static OtbakeBlend *blend_of_copies(const File *files, size_t nfiles, File *copies) {
  OtbakeProxy *proxy = NULL;
  OtbakeMap *maps[OTBAKE_MAX_MAPS] = {0};
  OtbakeBlend *blend = NULL;
  for (size_t i = 0; i < nfiles; i++) {
    copies[i].len = files[i].len;
    copies[i].bytes = aligned_alloc(16, (files[i].len + 15) / 16 * 16);
    memcpy(copies[i].bytes, files[i].bytes, files[i].len);
  }
  CHECK_STATUS(otbake_proxy_open(copies[0].bytes, copies[0].len, &proxy), OTBAKE_STATUS_OK);
  for (size_t i = 1; i < nfiles; i++) {
    CHECK_STATUS(otbake_map_open(copies[i].bytes, copies[i].len, &maps[i - 1]), OTBAKE_STATUS_OK);
  }
  CHECK_STATUS(otbake_blend_new(proxy, (const OtbakeMap *const *)maps, nfiles - 1, &blend), OTBAKE_STATUS_OK);
  otbake_proxy_free(proxy);
  for (size_t i = 0; i + 1 < nfiles; i++) otbake_map_free(maps[i]);
  return blend;
}

/* The records of one prepared section, collected for the batches at `pend`. */
typedef struct {
  size_t npoint, nrange, nsample;
  float sigma;
  float points[MAX_PRECORDS * 4], point_want[MAX_PRECORDS * 5];
  float lo[MAX_PRECORDS * 4], hi[MAX_PRECORDS * 4], range_want[MAX_PRECORDS * 5];
  uint32_t indices[MAX_PRECORDS];
  float sample_want[MAX_PRECORDS * 7];
} Section;

/* The point, range and sample records as batches, on handle `p`. */
static void batches(const OtbakePrepared *p, const Section *s, size_t d, int line) {
  OtbakePointValue pv[MAX_PRECORDS];
  float got[5];
  CHECK_STATUS(otbake_prepared_point_batch(p, s->points, d, s->npoint, s->sigma, pv), OTBAKE_STATUS_OK);
  for (size_t i = 0; i < s->npoint; i++) {
    point_value(&pv[i], got);
    same_f32(got, s->point_want + 5 * i, 5, "prepared point batch", line);
  }
  OtbakeRangeValue rv[MAX_PRECORDS];
  CHECK_STATUS(otbake_prepared_range_batch(p, s->lo, s->hi, d, s->nrange, rv), OTBAKE_STATUS_OK);
  for (size_t i = 0; i < s->nrange; i++) {
    float r[5] = {(float)rv[i].count, rv[i].mass, rv[i].color[0], rv[i].color[1], rv[i].color[2]};
    same_f32(r, s->range_want + 5 * i, 5, "prepared range batch", line);
  }
  OtbakeSample sv[MAX_PRECORDS];
  CHECK_STATUS(otbake_prepared_sample_batch(p, s->indices, s->nsample, sv), OTBAKE_STATUS_OK);
  for (size_t i = 0; i < s->nsample; i++) {
    same_f32(sv[i].position, s->sample_want + 7 * i, 4, "prepared sample batch position", line);
    same_f32(sv[i].color, s->sample_want + 7 * i + 4, 3, "prepared sample batch color", line);
  }
}

/* One grid record (pgrid, psplat, pregion, prgba) and its cells, through handle `p`. */
static void grid_record(const OtbakePrepared *p, char **t, FILE *f, int *line) {
  const char *tag = t[0];
  float sigma = f32_of(t[1]);
  uint32_t res[2] = {(uint32_t)strtoul(t[2], NULL, 10), (uint32_t)strtoul(t[3], NULL, 10)};
  OtbakeRegion region = {{res[0], res[1], 1, 1}, {0, 0, 0, 0}, {res[0], res[1], 1, 1}};
  size_t cells = 0, got_cells = 0;
  int grid = !strcmp(tag, "pgrid"), whole = !strcmp(tag, "psplat"), rgba = !strcmp(tag, "prgba");
  if (grid) {
    region.start[0] = (uint32_t)strtoul(t[4], NULL, 10);
    region.start[1] = (uint32_t)strtoul(t[5], NULL, 10);
    region.size[0] = (uint32_t)strtoul(t[6], NULL, 10);
    region.size[1] = (uint32_t)strtoul(t[7], NULL, 10);
    cells = strtoul(t[8], NULL, 10);
  } else if (whole) {
    cells = strtoul(t[4], NULL, 10);
  } else {
    region.start[1] = (uint32_t)strtoul(t[4], NULL, 10);
    region.size[1] = (uint32_t)strtoul(t[5], NULL, 10);
    cells = strtoul(t[6], NULL, 10);
  }
  size_t per = grid ? 5 : 4;
  float *want = calloc(cells * per, sizeof(float)), *got = calloc(cells * per, sizeof(float));
  int ok = read_cells(f, line, cells, per, want);
  if (whole) {
    CHECK_STATUS(otbake_prepared_grid_cells(p, res, 2, &got_cells), OTBAKE_STATUS_OK);
  } else {
    CHECK_STATUS(otbake_prepared_region_cells(p, region, &got_cells), OTBAKE_STATUS_OK);
  }
  CHECK(got_cells == cells, "%s: size query says %zu cells, Rust wrote %zu", tag, got_cells, cells);
  if (ok && got_cells == cells) {
    if (grid) {
      OtbakePointValue *v = calloc(cells, sizeof *v);
      CHECK_STATUS(otbake_prepared_point_grid(p, sigma, region, v, cells), OTBAKE_STATUS_OK);
      for (size_t c = 0; c < cells; c++) point_value(&v[c], got + 5 * c);
      /* Each cell is also the point query at its center (the runtime's promise). */
      for (size_t c = 0; c < cells; c += 7) {
        float q[2] = {((float)(region.start[0] + c % region.size[0]) + 0.5f) / (float)res[0],
                      ((float)(region.start[1] + c / region.size[0]) + 0.5f) / (float)res[1]};
        OtbakePointValue one;
        float pt[5];
        CHECK_STATUS(otbake_prepared_point(p, q, 2, sigma, &one), OTBAKE_STATUS_OK);
        point_value(&one, pt);
        same_f32(pt, got + 5 * c, 5, "point grid cell against a point query", *line);
      }
      free(v);
    } else if (rgba) {
      CHECK_STATUS(otbake_prepared_splat_region_rgba(p, sigma, region, got, 4 * cells), OTBAKE_STATUS_OK);
    } else {
      float *density = calloc(cells, sizeof(float)), *color = calloc(3 * cells, sizeof(float));
      if (whole) {
        CHECK_STATUS(otbake_prepared_splat(p, sigma, res, 2, density, cells, color, 3 * cells), OTBAKE_STATUS_OK);
      } else {
        CHECK_STATUS(otbake_prepared_splat_region(p, sigma, region, density, cells, color, 3 * cells),
                     OTBAKE_STATUS_OK);
      }
      for (size_t c = 0; c < cells; c++) {
        got[4 * c] = density[c];
        memcpy(got + 4 * c + 1, color + 3 * c, 3 * sizeof(float));
      }
      free(density);
      free(color);
    }
    same_f32(got, want, cells * per, tag, *line);
  }
  free(want);
  free(got);
}

size_t check_prepared(const OtbakeBlend *blend, const File *files, size_t nfiles, const float *w, size_t k,
                      char **t, size_t nt, FILE *f, int *line) {
  CHECK(nt == 7, "prepared line %d has %zu tokens", *line, nt);
  size_t total = strtoul(t[1], NULL, 10), npos = strtoul(t[3], NULL, 10), ncol = strtoul(t[5], NULL, 10);
  float mean_mass = f32_of(t[2]);
  uint64_t hpos = strtoull(t[4], NULL, 16), hcol = strtoull(t[6], NULL, 16);
  int first_line = *line;
  size_t records = 0;

  OtbakePreparedSizes sizes;
  CHECK_STATUS(otbake_blend_prepared_sizes(blend, &sizes), OTBAKE_STATUS_OK);
  CHECK(sizes.total == total, "size query says %zu floats, Rust's prepared_sizes %zu", sizes.total, total);
  CHECK(sizes.positions + sizes.colors + sizes.node_boxes + sizes.node_colors == sizes.total, "parts do not sum");

  /* Alone, from a blend of copied archives that is gone (and its bytes poisoned) before any query:
   * the handle reads its buffer only. The buffer is malloc'd: its contents on entry are ignored. */
  File copies[1 + OTBAKE_MAX_MAPS];
  OtbakeBlend *temporary = blend_of_copies(files, nfiles, copies);
  float *buf = malloc(total * sizeof(float));
  OtbakePrepared *p = NULL;
  CHECK_STATUS(otbake_prepared_new(temporary, w, k, buf, total, NULL, NULL, &p), OTBAKE_STATUS_OK);
  otbake_blend_free(temporary);
  for (size_t i = 0; i < nfiles; i++) {
    memset(copies[i].bytes, 0xa5, copies[i].len);
    free(copies[i].bytes);
  }
  /* With the halves on two threads, into a longer buffer; and with a join that runs neither. */
  int calls = 0;
  float *buf2 = malloc((total + 7) * sizeof(float)), *buf3 = malloc(total * sizeof(float));
  OtbakePrepared *p2 = NULL, *p3 = NULL;
  CHECK_STATUS(otbake_prepared_new(blend, w, k, buf2, total + 7, two_threads, &calls, &p2), OTBAKE_STATUS_OK);
  CHECK_STATUS(otbake_prepared_new(blend, w, k, buf3, total, lazy_join, &calls, &p3), OTBAKE_STATUS_OK);
  CHECK(calls == 2, "the joins were called %d times, not once each", calls);
  if (!p || !p2 || !p3) {
    fprintf(stderr, "cannot prepare the blend of line %d; skipping its section\n", first_line);
  } else {
    CHECK(!memcmp(buf, buf2, total * sizeof(float)), "the buffer prepared on two threads differs");
    CHECK(!memcmp(buf, buf3, total * sizeof(float)), "the buffer prepared by a lazy join differs");
    OtbakePreparedInfo info;
    CHECK_STATUS(otbake_prepared_info(p, &info), OTBAKE_STATUS_OK);
    same_f32(&info.mean_mass, &mean_mass, 1, "prepared mean mass", first_line);
    const float *positions = NULL, *colors = NULL;
    size_t plen = 0, clen = 0;
    CHECK_STATUS(otbake_prepared_positions(p, &positions, &plen), OTBAKE_STATUS_OK);
    CHECK_STATUS(otbake_prepared_colors(p, &colors, &clen), OTBAKE_STATUS_OK);
    CHECK(plen == npos && clen == ncol, "arrays of %zu and %zu floats, Rust's %zu and %zu", plen, clen, npos, ncol);
    CHECK(positions >= buf && positions + plen <= buf + total, "positions do not point into the buffer");
    CHECK(fnv(positions, plen) == hpos, "prepared positions differ from Rust's (hash)");
    CHECK(clen == 0 || fnv(colors, clen) == hcol, "prepared colors differ from Rust's (hash)");
    records += 1;
  }

  static Section s;
  memset(&s, 0, sizeof s);
  OtbakeBlendInfo binfo;
  CHECK_STATUS(otbake_blend_info(blend, &binfo), OTBAKE_STATUS_OK);
  size_t d = binfo.dim;
  char *text = NULL;
  size_t cap = 0;
  int ended = 0;
  while (!ended && getline(&text, &cap, f) >= 0) {
    (*line)++;
    char *tok[64], *save = NULL;
    size_t n = 0;
    for (char *x = strtok_r(text, " \n", &save); x && n < 64; x = strtok_r(NULL, " \n", &save)) tok[n++] = x;
    if (n == 0) continue;
    records++;
    float want[7], got[7];
    if (!strcmp(tok[0], "pend")) {
      ended = 1;
    } else if (!p) {
      continue;
    } else if (!strcmp(tok[0], "ppoint") && s.npoint < MAX_PRECORDS) {
      float sigma = f32_of(tok[1]), *q = s.points + d * s.npoint;
      for (size_t i = 0; i < d; i++) q[i] = f32_of(tok[2 + i]);
      for (size_t i = 0; i < 5; i++) want[i] = f32_of(tok[3 + d + i]);
      OtbakePointValue v;
      CHECK_STATUS(otbake_prepared_point(p, q, d, sigma, &v), OTBAKE_STATUS_OK);
      point_value(&v, got);
      same_f32(got, want, 5, "prepared point", *line);
      memcpy(s.point_want + 5 * s.npoint, want, sizeof(float) * 5);
      s.sigma = sigma;
      s.npoint++;
    } else if (!strcmp(tok[0], "prange") && s.nrange < MAX_PRECORDS) {
      float *lo = s.lo + d * s.nrange, *hi = s.hi + d * s.nrange;
      for (size_t i = 0; i < d; i++) {
        lo[i] = f32_of(tok[1 + i]);
        hi[i] = f32_of(tok[1 + d + i]);
      }
      want[0] = (float)strtoul(tok[2 + 2 * d], NULL, 10);
      for (size_t i = 0; i < 4; i++) want[1 + i] = f32_of(tok[3 + 2 * d + i]);
      OtbakeRangeValue r;
      CHECK_STATUS(otbake_prepared_range(p, lo, hi, d, &r), OTBAKE_STATUS_OK);
      float rv[5] = {(float)r.count, r.mass, r.color[0], r.color[1], r.color[2]};
      same_f32(rv, want, 5, "prepared range", *line);
      memcpy(s.range_want + 5 * s.nrange, want, sizeof(float) * 5);
      s.nrange++;
    } else if (!strcmp(tok[0], "psample") && s.nsample < MAX_PRECORDS) {
      uint32_t index = (uint32_t)strtoul(tok[1], NULL, 10);
      for (size_t i = 0; i < 7; i++) want[i] = f32_of(tok[3 + i]);
      OtbakeSample v;
      CHECK_STATUS(otbake_prepared_sample(p, index, &v), OTBAKE_STATUS_OK);
      same_f32(v.position, want, 4, "prepared sample position", *line);
      same_f32(v.color, want + 4, 3, "prepared sample color", *line);
      s.indices[s.nsample] = index;
      memcpy(s.sample_want + 7 * s.nsample, want, sizeof(float) * 7);
      s.nsample++;
    } else if (!strcmp(tok[0], "pgrid") || !strcmp(tok[0], "psplat") || !strcmp(tok[0], "pregion") ||
               !strcmp(tok[0], "prgba")) {
      /* Alternate the handles: every one of them must answer the same. */
      grid_record(records % 2 ? p : p2, tok, f, line);
    } else {
      CHECK(0, "unknown or overfull prepared record `%s` at line %d", tok[0], *line);
    }
  }
  CHECK(ended, "the prepared section of line %d has no pend", first_line);
  if (p && p2 && p3) {
    batches(p, &s, d, *line);
    batches(p2, &s, d, *line);
    batches(p3, &s, d, *line);
  }
  free(text);
  otbake_prepared_free(p);
  otbake_prepared_free(p2);
  otbake_prepared_free(p3);
  free(buf);
  free(buf2);
  free(buf3);
  return records;
}
