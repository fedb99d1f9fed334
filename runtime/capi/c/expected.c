/* The bit-for-bit half of the C test: repeats every record of the expected-values file (written
 * by the Rust program examples/c_expected.rs with otbake-runtime) through the C ABI, once per
 * record and as batches per section (shared weights, and per-element weights with a stride), and
 * compares the bits of every answer. */
#define _POSIX_C_SOURCE 200809L
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "check.h"

#define MAX_TOKENS 64
#define MAX_RECORDS 64

uint32_t bits(float x) {
  uint32_t u;
  memcpy(&u, &x, sizeof u);
  return u;
}

static uint64_t bits64(double x) {
  uint64_t u;
  memcpy(&u, &x, sizeof u);
  return u;
}

float f32_of(const char *hex) {
  uint32_t u = (uint32_t)strtoul(hex, NULL, 16);
  float x;
  memcpy(&x, &u, sizeof x);
  return x;
}

static double f64_of(const char *hex) {
  uint64_t u = (uint64_t)strtoull(hex, NULL, 16);
  double x;
  memcpy(&x, &u, sizeof x);
  return x;
}

/* Compares `n` floats bit for bit. */
void same_f32(const float *got, const float *want, size_t n, const char *what, int line) {
  for (size_t i = 0; i < n; i++) {
    CHECK(bits(got[i]) == bits(want[i]), "%s (record line %d) value %zu: C gave %a (%08x), Rust %a (%08x)",
          what, line, i, got[i], bits(got[i]), want[i], bits(want[i]));
  }
}

static void same_f64(const double *got, const double *want, size_t n, const char *what, int line) {
  for (size_t i = 0; i < n; i++) {
    CHECK(bits64(got[i]) == bits64(want[i]), "%s (record line %d) value %zu: C gave %a, Rust %a", what,
          line, i, got[i], want[i]);
  }
}

/* The state of one pass over the file: the open blend or BRDF, the weights, and the records of
 * the current section, run again as batches when the section ends. */
typedef struct {
  File files[1 + OTBAKE_MAX_MAPS];
  size_t nfiles;
  OtbakeBlend *blend;
  OtbakeBrdf *brdf;
  size_t dim;
  float w[OTBAKE_MAX_MAPS];
  size_t k;
  /* Section records (fixed-size: the generator writes at most MAX_RECORDS of each). */
  size_t npoint, nrange, nsample, neval, nangles, nbsample;
  float sigma;
  OtbakeAdaptiveKernel adaptive;
  float points[MAX_RECORDS * 4], point_want[MAX_RECORDS * 5], adaptive_want[MAX_RECORDS * 5];
  float lo[MAX_RECORDS * 4], hi[MAX_RECORDS * 4], range_want[MAX_RECORDS * 5];
  uint32_t indices[MAX_RECORDS];
  float sample_want[MAX_RECORDS * 7], bandwidth_want[MAX_RECORDS];
  double wi[MAX_RECORDS * 3], wo[MAX_RECORDS * 3];
  float eval_want[MAX_RECORDS * 3];
  double pdf_want[MAX_RECORDS];
  double angles[MAX_RECORDS * 3];
  float angles_want[MAX_RECORDS * 5];
  uint32_t bindices[MAX_RECORDS];
  double xi[MAX_RECORDS * 5], bsample_want64[MAX_RECORDS * 7];
  float bsample_want[MAX_RECORDS * 4];
  int line;
} State;

/* Weights for `count` elements, `k + 1` floats apart, the gap NaN (never read). */
static float *strided(const State *s, size_t count) {
  size_t stride = s->k + 1;
  float *w = malloc(sizeof(float) * stride * (count ? count : 1));
  for (size_t i = 0; i < count; i++) {
    memcpy(w + i * stride, s->w, sizeof(float) * s->k);
    w[i * stride + s->k] = NAN;
  }
  return w;
}

void point_value(const OtbakePointValue *v, float out[5]) {
  out[0] = v->density;
  out[1] = v->mass;
  memcpy(out + 2, v->color, sizeof(float) * 3);
}

/* Runs the section's blend records as batches, with shared and with per-element weights. */
static void flush_blend(State *s) {
  size_t n = s->npoint, d = s->dim, k = s->k;
  for (int per_element = 0; per_element < 2; per_element++) {
    float *ws = per_element ? strided(s, n) : s->w;
    size_t stride = per_element ? k + 1 : 0;
    OtbakePointValue pv[MAX_RECORDS];
    float got[5];
    CHECK_STATUS(otbake_blend_point_batch(s->blend, ws, k, stride, s->points, d, n, s->sigma, pv), OTBAKE_STATUS_OK);
    for (size_t i = 0; i < n; i++) {
      point_value(&pv[i], got);
      same_f32(got, s->point_want + 5 * i, 5, "point batch", s->line);
    }
    CHECK_STATUS(otbake_blend_point_adaptive_batch(s->blend, ws, k, stride, s->points, d, n, s->adaptive, pv),
                 OTBAKE_STATUS_OK);
    for (size_t i = 0; i < n; i++) {
      point_value(&pv[i], got);
      same_f32(got, s->adaptive_want + 5 * i, 5, "adaptive batch", s->line);
    }
    OtbakeRangeValue rv[MAX_RECORDS];
    CHECK_STATUS(otbake_blend_range_batch(s->blend, ws, k, stride, s->lo, s->hi, d, s->nrange, rv), OTBAKE_STATUS_OK);
    for (size_t i = 0; i < s->nrange; i++) {
      float r[5] = {(float)rv[i].count, rv[i].mass, rv[i].color[0], rv[i].color[1], rv[i].color[2]};
      same_f32(r, s->range_want + 5 * i, 5, "range batch", s->line);
    }
    OtbakeSample sv[MAX_RECORDS];
    CHECK_STATUS(otbake_blend_sample_batch(s->blend, ws, k, stride, s->indices, s->nsample, sv), OTBAKE_STATUS_OK);
    for (size_t i = 0; i < s->nsample; i++) {
      same_f32(sv[i].position, s->sample_want + 7 * i, 4, "sample batch position", s->line);
      same_f32(sv[i].color, s->sample_want + 7 * i + 4, 3, "sample batch color", s->line);
    }
    float bw[MAX_RECORDS];
    CHECK_STATUS(otbake_blend_bandwidth_batch(s->blend, ws, k, stride, s->indices, s->nsample, s->adaptive, bw),
                 OTBAKE_STATUS_OK);
    same_f32(bw, s->bandwidth_want, s->nsample, "bandwidth batch", s->line);
    if (per_element) free(ws);
  }
  s->npoint = s->nrange = s->nsample = 0;
}

/* Runs the section's BRDF records as batches, with shared and with per-element weights. */
static void flush_brdf(State *s) {
  size_t k = s->k;
  for (int per_element = 0; per_element < 2; per_element++) {
    size_t most = s->neval > s->nbsample ? s->neval : s->nbsample;
    float *ws = per_element ? strided(s, most > s->nangles ? most : s->nangles) : s->w;
    size_t stride = per_element ? k + 1 : 0;
    float rgb[MAX_RECORDS * 3];
    CHECK_STATUS(otbake_brdf_eval_batch(s->brdf, ws, k, stride, s->wi, s->wo, s->neval, rgb), OTBAKE_STATUS_OK);
    same_f32(rgb, s->eval_want, 3 * s->neval, "brdf eval batch", s->line);
    double pdf[MAX_RECORDS];
    CHECK_STATUS(otbake_brdf_pdf_batch(s->brdf, ws, k, stride, s->wi, s->wo, s->neval, pdf), OTBAKE_STATUS_OK);
    same_f64(pdf, s->pdf_want, s->neval, "brdf pdf batch", s->line);
    OtbakeBrdfValue v[MAX_RECORDS];
    CHECK_STATUS(otbake_brdf_eval_angles_batch(s->brdf, ws, k, stride, s->angles, s->nangles, v), OTBAKE_STATUS_OK);
    for (size_t i = 0; i < s->nangles; i++) {
      float got[5] = {v[i].rgb[0], v[i].rgb[1], v[i].rgb[2], v[i].luminance, v[i].density};
      same_f32(got, s->angles_want + 5 * i, 5, "brdf angles batch", s->line);
    }
    OtbakeBrdfSample bs[MAX_RECORDS];
    CHECK_STATUS(otbake_brdf_sample_batch(s->brdf, ws, k, stride, s->bindices, s->xi, s->nbsample, bs),
                 OTBAKE_STATUS_OK);
    for (size_t i = 0; i < s->nbsample; i++) {
      double got64[7] = {bs[i].wi[0], bs[i].wi[1], bs[i].wi[2], bs[i].wo[0], bs[i].wo[1], bs[i].wo[2], bs[i].pdf};
      same_f64(got64, s->bsample_want64 + 7 * i, 7, "brdf sample batch", s->line);
      float got[4] = {bs[i].value[0], bs[i].value[1], bs[i].value[2], bs[i].luminance};
      same_f32(got, s->bsample_want + 4 * i, 4, "brdf sample batch value", s->line);
    }
    if (per_element) free(ws);
  }
  s->neval = s->nangles = s->nbsample = 0;
}

static void flush(State *s) {
  if (s->blend && s->npoint) flush_blend(s);
  if (s->brdf && (s->neval || s->nbsample || s->nangles)) flush_brdf(s);
}

static void close_all(State *s) {
  flush(s);
  otbake_blend_free(s->blend);
  otbake_brdf_free(s->brdf);
  s->blend = NULL;
  s->brdf = NULL;
  for (size_t i = 0; i < s->nfiles; i++) free(s->files[i].bytes);
  s->nfiles = 0;
}

/* Opens `k + 1` archives named at `tok` (proxy first): the handles for a blend or BRDF. */
static void open_archives(State *s, char **tok, size_t k, OtbakeProxy **proxy, OtbakeMap **maps) {
  s->nfiles = k + 1;
  for (size_t i = 0; i <= k; i++) s->files[i] = read_file(tok[i]);
  CHECK_STATUS(otbake_proxy_open(s->files[0].bytes, s->files[0].len, proxy), OTBAKE_STATUS_OK);
  for (size_t i = 0; i < k; i++) {
    CHECK_STATUS(otbake_map_open(s->files[i + 1].bytes, s->files[i + 1].len, &maps[i]), OTBAKE_STATUS_OK);
  }
}

/* Frees the proxy and map handles: the blend holds its own views (the bytes stay). */
static void free_handles(OtbakeProxy *proxy, OtbakeMap **maps, size_t k) {
  otbake_proxy_free(proxy);
  for (size_t i = 0; i < k; i++) otbake_map_free(maps[i]);
}

/* One blend record (point, adaptive, range, sample, bandwidth): the single call now, the batch
 * later. */
static void blend_record(State *s, char **t, size_t nt) {
  size_t d = s->dim, k = s->k;
  float want[7], got[7];
  (void)nt;
  if (!strcmp(t[0], "point") && s->npoint < MAX_RECORDS) {
    float sigma = f32_of(t[1]), *p = s->points + d * s->npoint;
    for (size_t i = 0; i < d; i++) p[i] = f32_of(t[2 + i]);
    for (size_t i = 0; i < 5; i++) want[i] = f32_of(t[3 + d + i]);
    OtbakePointValue v;
    CHECK_STATUS(otbake_blend_point(s->blend, s->w, k, p, d, sigma, &v), OTBAKE_STATUS_OK);
    point_value(&v, got);
    same_f32(got, want, 5, "point", s->line);
    memcpy(s->point_want + 5 * s->npoint, want, sizeof(float) * 5);
    s->sigma = sigma;
    s->npoint++;
  } else if (!strcmp(t[0], "adaptive")) {
    OtbakeAdaptiveKernel ak = {f32_of(t[1]), f32_of(t[2]), f32_of(t[3])};
    float p[4];
    for (size_t i = 0; i < d; i++) p[i] = f32_of(t[4 + i]);
    for (size_t i = 0; i < 5; i++) want[i] = f32_of(t[5 + d + i]);
    OtbakePointValue v;
    CHECK_STATUS(otbake_blend_point_adaptive(s->blend, s->w, k, p, d, ak, &v), OTBAKE_STATUS_OK);
    point_value(&v, got);
    same_f32(got, want, 5, "adaptive", s->line);
    memcpy(s->adaptive_want + 5 * (s->npoint - 1), want, sizeof(float) * 5);
    s->adaptive = ak;
  } else if (!strcmp(t[0], "range") && s->nrange < MAX_RECORDS) {
    float *lo = s->lo + d * s->nrange, *hi = s->hi + d * s->nrange;
    for (size_t i = 0; i < d; i++) {
      lo[i] = f32_of(t[1 + i]);
      hi[i] = f32_of(t[1 + d + i]);
    }
    want[0] = (float)strtoul(t[2 + 2 * d], NULL, 10);
    for (size_t i = 0; i < 4; i++) want[1 + i] = f32_of(t[3 + 2 * d + i]);
    OtbakeRangeValue r;
    CHECK_STATUS(otbake_blend_range(s->blend, s->w, k, lo, hi, d, &r), OTBAKE_STATUS_OK);
    float rv[5] = {(float)r.count, r.mass, r.color[0], r.color[1], r.color[2]};
    same_f32(rv, want, 5, "range", s->line);
    memcpy(s->range_want + 5 * s->nrange, want, sizeof(float) * 5);
    s->nrange++;
  } else if (!strcmp(t[0], "sample") && s->nsample < MAX_RECORDS) {
    uint32_t index = (uint32_t)strtoul(t[1], NULL, 10);
    for (size_t i = 0; i < 7; i++) want[i] = f32_of(t[3 + i]);
    OtbakeSample v;
    CHECK_STATUS(otbake_blend_sample(s->blend, s->w, k, index, &v), OTBAKE_STATUS_OK);
    same_f32(v.position, want, 4, "sample position", s->line);
    same_f32(v.color, want + 4, 3, "sample color", s->line);
    s->indices[s->nsample] = index;
    memcpy(s->sample_want + 7 * s->nsample, want, sizeof(float) * 7);
    s->nsample++;
  } else if (!strcmp(t[0], "bandwidth")) {
    OtbakeAdaptiveKernel ak = {f32_of(t[1]), f32_of(t[2]), f32_of(t[3])};
    uint32_t index = (uint32_t)strtoul(t[4], NULL, 10);
    float sigma, w1 = f32_of(t[6]);
    CHECK_STATUS(otbake_blend_bandwidth(s->blend, s->w, k, index, ak, &sigma), OTBAKE_STATUS_OK);
    same_f32(&sigma, &w1, 1, "bandwidth", s->line);
    s->bandwidth_want[s->nsample - 1] = w1;
  } else {
    CHECK(0, "unknown or overfull record `%s` at line %d", t[0], s->line);
  }
}

/* A splat section: `splat` (planar, whole grid) or `rgba` (a band of rows), then its cells. */
static void splat_record(State *s, char **t, FILE *f) {
  int rgba = !strcmp(t[0], "rgba");
  float sigma = f32_of(t[1]);
  uint32_t res[2] = {(uint32_t)strtoul(t[2], NULL, 10), (uint32_t)strtoul(t[3], NULL, 10)};
  size_t cells = strtoul(t[rgba ? 6 : 4], NULL, 10), got_cells = 0;
  float *a = calloc(cells * 4, sizeof(float)), *b = calloc(cells * 3, sizeof(float));
  if (rgba) {
    OtbakeRegion region = {{res[0], res[1], 1, 1}, {0, 0, 0, 0}, {res[0], 1, 1, 1}};
    region.start[1] = (uint32_t)strtoul(t[4], NULL, 10);
    region.size[1] = (uint32_t)strtoul(t[5], NULL, 10);
    CHECK_STATUS(otbake_blend_region_cells(s->blend, region, &got_cells), OTBAKE_STATUS_OK);
    CHECK_STATUS(otbake_blend_splat_region_rgba(s->blend, s->w, s->k, sigma, region, a, 4 * cells), OTBAKE_STATUS_OK);
  } else {
    CHECK_STATUS(otbake_blend_grid_cells(s->blend, res, 2, &got_cells), OTBAKE_STATUS_OK);
    CHECK_STATUS(otbake_blend_splat(s->blend, s->w, s->k, sigma, res, 2, a, cells, b, 3 * cells), OTBAKE_STATUS_OK);
  }
  CHECK(got_cells == cells, "size query says %zu cells, Rust splatted %zu", got_cells, cells);
  char *line = NULL;
  size_t cap = 0;
  for (size_t c = 0; c < cells; c++) {
    s->line++;
    if (getline(&line, &cap, f) < 0) {
      CHECK(0, "expected file ends inside a splat");
      break;
    }
    float want[4], got[4];
    char *save = NULL, *tok = strtok_r(line, " \n", &save);
    for (size_t i = 0; i < (size_t)(rgba ? 4 : 4); i++) want[i] = f32_of(strtok_r(NULL, " \n", &save));
    (void)tok;
    if (rgba) {
      memcpy(got, a + 4 * c, sizeof got);
    } else {
      got[0] = a[c];
      memcpy(got + 1, b + 3 * c, sizeof(float) * 3);
    }
    same_f32(got, want, 4, rgba ? "rgba splat cell" : "splat cell", s->line);
  }
  free(line);
  free(a);
  free(b);
}

/* One BRDF record (eval, pdf, angles, bsample): the single call now, the batch later. */
static void brdf_record(State *s, char **t) {
  size_t k = s->k;
  if (!strcmp(t[0], "eval") && s->neval < MAX_RECORDS) {
    double *wi = s->wi + 3 * s->neval, *wo = s->wo + 3 * s->neval;
    float *want = s->eval_want + 3 * s->neval, got[3];
    for (size_t i = 0; i < 3; i++) {
      wi[i] = f64_of(t[1 + i]);
      wo[i] = f64_of(t[4 + i]);
      want[i] = f32_of(t[8 + i]);
    }
    CHECK_STATUS(otbake_brdf_eval(s->brdf, s->w, k, wi, wo, got), OTBAKE_STATUS_OK);
    same_f32(got, want, 3, "brdf eval", s->line);
    s->neval++;
  } else if (!strcmp(t[0], "pdf")) {
    double wi[3], wo[3], want = f64_of(t[8]), got;
    for (size_t i = 0; i < 3; i++) {
      wi[i] = f64_of(t[1 + i]);
      wo[i] = f64_of(t[4 + i]);
    }
    CHECK_STATUS(otbake_brdf_pdf(s->brdf, s->w, k, wi, wo, &got), OTBAKE_STATUS_OK);
    same_f64(&got, &want, 1, "brdf pdf", s->line);
    s->pdf_want[s->neval - 1] = want;
  } else if (!strcmp(t[0], "angles") && s->nangles < MAX_RECORDS) {
    double *a = s->angles + 3 * s->nangles;
    float *want = s->angles_want + 5 * s->nangles;
    for (size_t i = 0; i < 3; i++) a[i] = f64_of(t[1 + i]);
    for (size_t i = 0; i < 5; i++) want[i] = f32_of(t[5 + i]);
    OtbakeBrdfValue v;
    CHECK_STATUS(otbake_brdf_eval_angles_batch(s->brdf, s->w, k, 0, a, 1, &v), OTBAKE_STATUS_OK);
    float got[5] = {v.rgb[0], v.rgb[1], v.rgb[2], v.luminance, v.density};
    same_f32(got, want, 5, "brdf angles", s->line);
    s->nangles++;
  } else if (!strcmp(t[0], "bsample") && s->nbsample < MAX_RECORDS) {
    uint32_t index = (uint32_t)strtoul(t[1], NULL, 10);
    double *xi = s->xi + 5 * s->nbsample, *want64 = s->bsample_want64 + 7 * s->nbsample;
    float *want = s->bsample_want + 4 * s->nbsample;
    for (size_t i = 0; i < 5; i++) xi[i] = f64_of(t[2 + i]);
    for (size_t i = 0; i < 7; i++) want64[i] = f64_of(t[8 + i]);
    for (size_t i = 0; i < 4; i++) want[i] = f32_of(t[15 + i]);
    OtbakeBrdfSample v;
    CHECK_STATUS(otbake_brdf_sample(s->brdf, s->w, k, index, xi, &v), OTBAKE_STATUS_OK);
    double got64[7] = {v.wi[0], v.wi[1], v.wi[2], v.wo[0], v.wo[1], v.wo[2], v.pdf};
    same_f64(got64, want64, 7, "brdf sample", s->line);
    float got[4] = {v.value[0], v.value[1], v.value[2], v.luminance};
    same_f32(got, want, 4, "brdf sample value", s->line);
    s->bindices[s->nbsample++] = index;
  } else {
    CHECK(0, "unknown or overfull record `%s` at line %d", t[0], s->line);
  }
}

void check_expected(const char *expected_path) {
  FILE *f = fopen(expected_path, "r");
  if (!f) {
    fprintf(stderr, "cannot open %s: run examples/c_expected first (runtime/capi/ci.sh does)\n", expected_path);
    exit(2);
  }
  static State s;
  memset(&s, 0, sizeof s);
  char *line = NULL;
  size_t cap = 0;
  size_t records = 0;
  while (getline(&line, &cap, f) >= 0) {
    s.line++;
    char *t[MAX_TOKENS], *save = NULL;
    size_t nt = 0;
    for (char *tok = strtok_r(line, " \n", &save); tok && nt < MAX_TOKENS; tok = strtok_r(NULL, " \n", &save)) {
      t[nt++] = tok;
    }
    if (nt == 0) continue;
    records++;
    if (!strcmp(t[0], "blend") || !strcmp(t[0], "brdf")) {
      close_all(&s);
      OtbakeProxy *proxy = NULL;
      OtbakeMap *maps[OTBAKE_MAX_MAPS] = {0};
      int is_brdf = !strcmp(t[0], "brdf"), adaptive = is_brdf && !strcmp(t[1], "adaptive");
      size_t at = !is_brdf ? 1 : adaptive ? 5 : 3; /* index of k */
      size_t k = strtoul(t[at], NULL, 10);
      open_archives(&s, t + at + 1, k, &proxy, maps);
      OtbakeBlendInfo info;
      if (!is_brdf) {
        CHECK_STATUS(otbake_blend_new(proxy, (const OtbakeMap *const *)maps, k, &s.blend), OTBAKE_STATUS_OK);
        CHECK_STATUS(otbake_blend_info(s.blend, &info), OTBAKE_STATUS_OK);
      } else if (adaptive) {
        OtbakeAdaptiveKernel ak = {f32_of(t[2]), f32_of(t[3]), f32_of(t[4])};
        OtbakeAdaptiveKernel def = otbake_brdf_default_kernel();
        CHECK(bits(def.scale) == bits(ak.scale) && bits(def.max_sigma) == bits(ak.max_sigma),
              "the default BRDF kernel differs from otbake-brdf's");
        CHECK_STATUS(otbake_brdf_new_adaptive(proxy, (const OtbakeMap *const *)maps, k, ak, &s.brdf),
                     OTBAKE_STATUS_OK);
        CHECK_STATUS(otbake_brdf_info(s.brdf, &info), OTBAKE_STATUS_OK);
      } else {
        CHECK_STATUS(otbake_brdf_new_fixed(proxy, (const OtbakeMap *const *)maps, k, f32_of(t[2]), &s.brdf),
                     OTBAKE_STATUS_OK);
        CHECK_STATUS(otbake_brdf_info(s.brdf, &info), OTBAKE_STATUS_OK);
      }
      free_handles(proxy, maps, k);
      s.dim = info.dim;
      CHECK(info.k == k, "info says k = %u, the record %zu", info.k, k);
      if (s.blend == NULL && s.brdf == NULL) {
        fprintf(stderr, "cannot open the archives of line %d; stopping\n", s.line);
        break;
      }
    } else if (!strcmp(t[0], "weights")) {
      flush(&s);
      s.k = strtoul(t[1], NULL, 10);
      for (size_t i = 0; i < s.k; i++) s.w[i] = f32_of(t[2 + i]);
    } else if (!strcmp(t[0], "splat") || !strcmp(t[0], "rgba")) {
      flush(&s);
      splat_record(&s, t, f);
    } else if (!strcmp(t[0], "prepared")) {
      flush(&s);
      records += check_prepared(s.blend, s.files, s.nfiles, s.w, s.k, t, nt, f, &s.line);
    } else if (s.brdf) {
      brdf_record(&s, t);
    } else {
      blend_record(&s, t, nt);
    }
  }
  close_all(&s);
  free(line);
  fclose(f);
  CHECK(records > 100, "only %zu records in %s", records, expected_path);
  printf("expected: %zu records checked bit for bit (single calls and batches)\n", records);
}
