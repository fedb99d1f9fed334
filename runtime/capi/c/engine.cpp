// What an engine does with otbake's C ABI: map the archive files into memory (zero copy), make
// one blend, and every frame splat it with new weights into an RGBA image — in bands of rows, one
// per worker thread, no allocation by otbake — then write the frame (binary PPM).
//
//   otbake_engine [--mode blend|prepared] [--sigma PX] [--no-write] OUT_PREFIX FRAMES SIZE PROXY MAP...
//
// writes OUT_PREFIX-000.ppm ... (FRAMES images of SIZE x SIZE). Weights travel around the
// inputs: frame t of T blends inputs i and i+1 at phase t*k/T. Exits non-zero on any refusal, or
// if a frame is black (so a CI run checks that something was drawn).
//
// Modes (both draw the same bits):
//   blend     (the default, and what an engine should do when the weights change every frame)
//             otbake_blend_splat_region_rgba per band: the maps are mixed as each band reads them;
//   prepared  otbake_prepared_new once per frame (its two halves on two threads, into one buffer
//             allocated at load time), then otbake_prepared_splat_region_rgba per band: the way
//             to go when one weight vector serves many queries (point grids, thousands of point
//             queries, several splats), measured slower for one splat a frame (BENCHMARKS.md).
// --sigma is the kernel's width in pixels (default 0.75). Prints the median time per frame (wall
// and process CPU, the PPM write excluded); --no-write skips writing the frames (for timing).
#include <sys/mman.h>
#include <sys/stat.h>
#include <fcntl.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstring>
#include <ctime>
#include <cstdio>
#include <cstdlib>
#include <memory>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

#include "otbake.h"

namespace {

// Throws with the status's message and the detailed last error of this thread.
void check(OtbakeStatus status, const char *what) {
  if (status != OTBAKE_STATUS_OK) {
    throw std::runtime_error(std::string(what) + ": " + otbake_status_message(status) + " (" +
                             otbake_last_error() + ")");
  }
}

// A read-only mapping of a whole file: page-aligned, so 16-byte aligned as otbake needs. It must
// outlive every handle opened from it.
class Mapping {
 public:
  explicit Mapping(const char *path) {
    int fd = open(path, O_RDONLY);
    if (fd < 0) throw std::runtime_error(std::string("cannot open ") + path);
    struct stat st;
    if (fstat(fd, &st) != 0 || st.st_size == 0) {
      close(fd);
      throw std::runtime_error(std::string("cannot stat or empty: ") + path);
    }
    len_ = static_cast<size_t>(st.st_size);
    data_ = mmap(nullptr, len_, PROT_READ, MAP_PRIVATE, fd, 0);
    close(fd);
    if (data_ == MAP_FAILED) throw std::runtime_error(std::string("cannot map ") + path);
  }
  ~Mapping() { munmap(data_, len_); }
  Mapping(const Mapping &) = delete;
  Mapping &operator=(const Mapping &) = delete;
  const uint8_t *bytes() const { return static_cast<const uint8_t *>(data_); }
  size_t len() const { return len_; }

 private:
  void *data_ = nullptr;
  size_t len_ = 0;
};

struct ProxyFree {
  void operator()(OtbakeProxy *p) const { otbake_proxy_free(p); }
};
struct MapFree {
  void operator()(OtbakeMap *m) const { otbake_map_free(m); }
};
struct BlendFree {
  void operator()(OtbakeBlend *b) const { otbake_blend_free(b); }
};

// Weights of frame t of `frames` for k inputs: between input i and i+1, moving once around.
std::vector<float> frame_weights(int t, int frames, size_t k) {
  std::vector<float> w(k, 0.0f);
  double phase = static_cast<double>(t) * static_cast<double>(k) / frames;
  size_t i = static_cast<size_t>(phase) % k;
  float f = static_cast<float>(phase - std::floor(phase));
  w[i] += 1.0f - f;
  w[(i + 1) % k] += f;
  return w;
}

// Writes premultiplied RGBA (alpha = density) as an 8-bit PPM, scaled by the frame's brightest
// channel; returns the sum of the bytes written (0: a black frame).
unsigned long write_ppm(const std::string &path, const std::vector<float> &rgba, uint32_t size) {
  float peak = 0.0f;
  for (size_t c = 0; c < rgba.size(); c += 4) {
    peak = std::max({peak, rgba[c], rgba[c + 1], rgba[c + 2]});
  }
  std::string tmp = path + ".tmp";
  FILE *f = std::fopen(tmp.c_str(), "wb");
  if (!f) throw std::runtime_error("cannot write " + tmp);
  std::fprintf(f, "P6\n%u %u\n255\n", size, size);
  unsigned long sum = 0;
  // Row 0 of the grid is y = 0, the bottom of the image: write rows top down.
  for (uint32_t y = size; y-- > 0;) {
    for (uint32_t x = 0; x < size; x++) {
      const float *px = &rgba[4 * (static_cast<size_t>(y) * size + x)];
      for (int ch = 0; ch < 3; ch++) {
        float v = peak > 0.0f ? std::pow(std::clamp(px[ch] / peak, 0.0f, 1.0f), 1.0f / 2.2f) : 0.0f;
        unsigned char byte = static_cast<unsigned char>(std::lround(v * 255.0f));
        sum += byte;
        std::fputc(byte, f);
      }
    }
  }
  if (std::fclose(f) != 0 || std::rename(tmp.c_str(), path.c_str()) != 0) {
    throw std::runtime_error("cannot write " + path);
  }
  return sum;
}

// A join for otbake_prepared_new: the two halves of the mixing on a new thread and this one.
void join_on_two_threads(void *, OtbakeTaskFn run, void *a, void *b) {
  std::thread other([run, a] { run(a); });
  run(b);
  other.join();
}

// Process CPU seconds (all threads).
double cpu_seconds() {
  timespec ts;
  clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &ts);
  return static_cast<double>(ts.tv_sec) + 1e-9 * static_cast<double>(ts.tv_nsec);
}

double median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  return v.empty() ? 0.0 : v[v.size() / 2];
}

int run(int argc, char **argv) {
  bool prepared_mode = false, write = true;
  float sigma_px = 0.75f;
  int a0 = 1;
  for (; a0 < argc && std::strncmp(argv[a0], "--", 2) == 0; a0++) {
    if (!std::strcmp(argv[a0], "--no-write")) {
      write = false;
    } else if (!std::strcmp(argv[a0], "--sigma") && a0 + 1 < argc) {
      sigma_px = std::strtof(argv[++a0], nullptr);
      if (!(sigma_px > 0.0f)) throw std::runtime_error("--sigma must be a positive number of pixels");
    } else if (!std::strcmp(argv[a0], "--mode") && a0 + 1 < argc) {
      const std::string m = argv[++a0];
      if (m != "blend" && m != "prepared") throw std::runtime_error("--mode is blend or prepared, not " + m);
      prepared_mode = m == "prepared";
    } else {
      throw std::runtime_error(std::string("unknown option ") + argv[a0]);
    }
  }
  argc -= a0 - 1;
  argv += a0 - 1;
  if (argc < 6) {
    std::fprintf(stderr, "usage: otbake_engine [--mode blend|prepared] [--sigma PX] [--no-write] OUT_PREFIX FRAMES SIZE PROXY MAP...\n");
    return 2;
  }
  if (otbake_abi_version() != OTBAKE_ABI_VERSION) throw std::runtime_error("otbake.h and the library differ");
  const std::string prefix = argv[1];
  const int frames = std::atoi(argv[2]);
  const uint32_t size = static_cast<uint32_t>(std::atoi(argv[3]));
  if (frames < 1 || size < 1) throw std::runtime_error("FRAMES and SIZE must be >= 1");

  // Load time: map the files, open, blend. The proxy and map handles may go once the blend
  // exists; the mappings may not.
  std::vector<std::unique_ptr<Mapping>> files;
  for (int a = 4; a < argc; a++) files.push_back(std::make_unique<Mapping>(argv[a]));
  OtbakeProxy *raw_proxy = nullptr;
  check(otbake_proxy_open(files[0]->bytes(), files[0]->len(), &raw_proxy), argv[4]);
  std::unique_ptr<OtbakeProxy, ProxyFree> proxy(raw_proxy);
  std::vector<std::unique_ptr<OtbakeMap, MapFree>> maps;
  std::vector<const OtbakeMap *> views;
  for (size_t i = 1; i < files.size(); i++) {
    OtbakeMap *m = nullptr;
    check(otbake_map_open(files[i]->bytes(), files[i]->len(), &m), argv[4 + i]);
    maps.emplace_back(m);
    views.push_back(m);
  }
  OtbakeBlend *raw_blend = nullptr;
  check(otbake_blend_new(proxy.get(), views.data(), views.size(), &raw_blend), "blend");
  std::unique_ptr<OtbakeBlend, BlendFree> blend(raw_blend);
  maps.clear();
  proxy.reset();
  OtbakeBlendInfo info;
  check(otbake_blend_info(blend.get(), &info), "info");
  if (info.dim != 2) throw std::runtime_error("this example draws 2D blends");

  // The prepared mode's buffer, sized and allocated once at load time.
  OtbakePreparedSizes sizes;
  check(otbake_blend_prepared_sizes(blend.get(), &sizes), "prepared sizes");
  std::vector<float> buffer(prepared_mode ? sizes.total : 0);

  // Per frame: new weights, one region splat per band of rows, each on its own thread.
  const unsigned workers = std::max(2u, std::thread::hardware_concurrency());
  const float sigma = sigma_px / static_cast<float>(size);
  std::vector<float> rgba(4 * static_cast<size_t>(size) * size);
  std::vector<double> walls, cpus;
  for (int t = 0; t < frames; t++) {
    std::vector<float> w = frame_weights(t, frames, info.k);
    const auto wall0 = std::chrono::steady_clock::now();
    const double cpu0 = cpu_seconds();
    std::fill(rgba.begin(), rgba.end(), 0.0f);
    OtbakePrepared *prepared = nullptr;
    if (prepared_mode) {
      // The handle reads only `buffer`, which stays untouched until it is freed below.
      check(otbake_prepared_new(blend.get(), w.data(), w.size(), buffer.data(), buffer.size(), join_on_two_threads,
                                nullptr, &prepared),
            "prepare");
    }
    std::vector<std::thread> pool;
    std::vector<OtbakeStatus> status(workers, OTBAKE_STATUS_OK);
    const uint32_t band = (size + workers - 1) / workers;
    for (unsigned j = 0; j < workers; j++) {
      const uint32_t first = j * band;
      if (first >= size) break;
      const uint32_t rows = std::min(band, size - first);
      pool.emplace_back([&, j, first, rows] {
        OtbakeRegion region = {{size, size, 1, 1}, {0, first, 0, 0}, {size, rows, 1, 1}};
        float *out = &rgba[4 * static_cast<size_t>(first) * size];
        const size_t len = 4 * static_cast<size_t>(rows) * size;
        status[j] = prepared ? otbake_prepared_splat_region_rgba(prepared, sigma, region, out, len)
                             : otbake_blend_splat_region_rgba(blend.get(), w.data(), w.size(), sigma, region, out, len);
      });
    }
    for (auto &th : pool) th.join();
    otbake_prepared_free(prepared);
    cpus.push_back(cpu_seconds() - cpu0);
    walls.push_back(std::chrono::duration<double>(std::chrono::steady_clock::now() - wall0).count());
    for (OtbakeStatus s : status) check(s, "splat");
    unsigned long sum = 0;
    for (size_t c = 0; c < rgba.size(); c += 4) sum += rgba[c + 3] > 0.0f;
    if (sum == 0) throw std::runtime_error("frame " + std::to_string(t) + " is black");
    if (write) {
      char name[32];
      std::snprintf(name, sizeof name, "-%03d.ppm", t);
      if (write_ppm(prefix + name, rgba, size) == 0) throw std::runtime_error("frame " + std::to_string(t) + " is black");
    }
  }
  std::printf("engine: %s mode, %d frames of %ux%u from %u maps, %u threads per frame; median frame %.3f ms wall, "
              "%.3f ms CPU\n",
              prepared_mode ? "prepared" : "blend", frames, size, size, info.k, workers, 1e3 * median(walls),
              1e3 * median(cpus));
  return 0;
}

}  // namespace

int main(int argc, char **argv) {
  try {
    return run(argc, argv);
  } catch (const std::exception &e) {
    std::fprintf(stderr, "otbake_engine: %s\n", e.what());
    return 1;
  }
}
