// What an engine does with otbake's C ABI: map the archive files into memory (zero copy), make
// one blend, and every frame splat it with new weights into an RGBA image — in bands of rows, one
// per worker thread, no allocation by otbake — then write the frame (binary PPM).
//
//   otbake_engine OUT_PREFIX FRAMES SIZE PROXY MAP...
//
// writes OUT_PREFIX-000.ppm ... (FRAMES images of SIZE x SIZE). Weights travel around the
// inputs: frame t of T blends inputs i and i+1 at phase t*k/T. Exits non-zero on any refusal, or
// if a frame is black (so a CI run checks that something was drawn).
#include <sys/mman.h>
#include <sys/stat.h>
#include <fcntl.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
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

int run(int argc, char **argv) {
  if (argc < 6) {
    std::fprintf(stderr, "usage: %s OUT_PREFIX FRAMES SIZE PROXY MAP...\n", argv[0]);
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

  // Per frame: new weights, one region splat per band of rows, each on its own thread.
  const unsigned workers = std::max(2u, std::thread::hardware_concurrency());
  const float sigma = 0.75f / static_cast<float>(size);  // three quarters of a pixel
  std::vector<float> rgba(4 * static_cast<size_t>(size) * size);
  for (int t = 0; t < frames; t++) {
    std::vector<float> w = frame_weights(t, frames, info.k);
    std::fill(rgba.begin(), rgba.end(), 0.0f);
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
        status[j] = otbake_blend_splat_region_rgba(blend.get(), w.data(), w.size(), sigma, region, out,
                                                   4 * static_cast<size_t>(rows) * size);
      });
    }
    for (auto &th : pool) th.join();
    for (OtbakeStatus s : status) check(s, "splat");
    char name[32];
    std::snprintf(name, sizeof name, "-%03d.ppm", t);
    if (write_ppm(prefix + name, rgba, size) == 0) throw std::runtime_error("frame " + std::to_string(t) + " is black");
  }
  std::printf("engine: %d frames of %ux%u from %u maps, %u threads per frame\n", frames, size, size, info.k, workers);
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
