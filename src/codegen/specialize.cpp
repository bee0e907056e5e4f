// src/codegen/specialize.cpp — per-robot compiled instances: source, cache
// key, compilation with the system's compiler, loading (rbdkit/codegen/specialize.hpp).
#include "rbdkit/codegen/specialize.hpp"

#include <dlfcn.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cctype>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <map>
#include <mutex>
#include <sstream>
#include <stdexcept>
#include <vector>

#include "rbdkit/codegen/generate.hpp"
#include "rbdkit/codegen/instance.hpp"
#include "rbdkit/cuda/instance.cuh"

#ifndef RBDKIT_SOURCE_INCLUDE_DIR
#define RBDKIT_SOURCE_INCLUDE_DIR ""
#endif

namespace fs = std::filesystem;

namespace rbd {

struct Instance {
  std::string path;
  void* library = nullptr;
  std::vector<ops::Kernel<double>> kernels;  // per registered operation (null: none)
  ~Instance() {
    if (library) dlclose(library);
  }
};

struct CudaInstance {
  std::string path;
  void* library = nullptr;
  const cuda::instance::Description* description = nullptr;
  std::vector<const void*> f64, f32;  // per registered operation: its launch (null: none)
  ~CudaInstance() {
    if (library) dlclose(library);
  }
};

namespace {

constexpr const char* kStructName = "Robot";

// the cache key: FNV-1a (instance.hpp's) over strings, each followed by a separator byte (not a
// security boundary: open_instance checks who may write the library)
struct Hash {
  uint64_t h = instance::kFnvBasis;
  void add(const std::string& s) {
    for (unsigned char c : s) h = instance::mix_byte(h, c);
    h = instance::mix_byte(h, 0xff);
  }
  std::string hex() const {
    char b[17];
    std::snprintf(b, sizeof b, "%016llx", static_cast<unsigned long long>(h));
    return b;
  }
};

std::string env(const char* name) {
  const char* v = std::getenv(name);
  return v ? v : "";
}

std::string read_file(const fs::path& p) {
  std::ifstream f(p, std::ios::binary);
  std::ostringstream s;
  s << f.rdbuf();
  return s.str();
}

// a word for the shell, in single quotes (one with a quote in it is refused)
std::string quoted(const std::string& s, const char* what) {
  if (s.find('\'') != std::string::npos)
    throw std::runtime_error(std::string("specialize: the ") + what + " '" + s + "' contains a quote");
  return "'" + s + "'";
}

// the compiler command ("ccache g++" is two words), each word quoted
std::string compiler_command(const std::string& compiler) {
  std::istringstream words(compiler);
  std::string w, out;
  while (words >> w) out += (out.empty() ? "" : " ") + quoted(w, "compiler");
  if (out.empty()) throw std::runtime_error("specialize: the compiler is empty");
  return out;
}

// what a shell command prints (stdout and stderr), "" if it cannot run
std::string output_of(const std::string& cmd) {
  std::string out;
  if (FILE* p = popen((cmd + " 2>&1").c_str(), "r")) {
    char b[512];
    for (size_t n; (n = std::fread(b, 1, sizeof b, p)) > 0;) out.append(b, n);
    pclose(p);
  }
  return out;
}

fs::path cache_folder(const SpecializeOptions& o) {
  if (!o.cache_dir.empty()) return o.cache_dir;
  if (!env("RBDKIT_CACHE_DIR").empty()) return env("RBDKIT_CACHE_DIR");
  if (!env("XDG_CACHE_HOME").empty()) return fs::path(env("XDG_CACHE_HOME")) / "rbdkit";
  if (!env("HOME").empty()) return fs::path(env("HOME")) / ".cache" / "rbdkit";
  return fs::temp_directory_path() / ("rbdkit-cache-" + std::to_string(::geteuid()));  // (a folder per user)
}

// the compile command's fixed options (the key hashes them with the rest): the C++ compiler's, and
// nvcc's (a CUDA instance's real kernels; host options through -Xcompiler)
constexpr const char* kFixedFlags = "-std=c++17 -fPIC -shared -fvisibility=hidden";
constexpr const char* kNvccFixedFlags = "-std=c++17 -shared -Xcompiler -fPIC,-fvisibility=hidden";

// how an instance is compiled: the compiler command, its fixed options, the caller's, the source's
// file extension
struct Build {
  std::string compiler, fixed, flags, extension;
};

// the key: the instance ABI, the source (so every constant of the model), the compiler's command and
// version, the flags, the CPU's features (for -march=native) and every rbdkit header (the source
// includes most of them, and a changed one changes what the library computes)
std::string cache_key(const std::string& source, const Build& b, const fs::path& include_dir,
                      const std::string& extra) {
  Hash h;
  h.add(std::to_string(instance::kAbi));
  h.add(extra);
  h.add(source);
  h.add(b.compiler);
  h.add(output_of(compiler_command(b.compiler) + " --version"));
  h.add(b.flags);
  h.add(b.fixed);
  {  // the CPU's model and flags (Linux), which -march=native resolves to
    std::ifstream cpu("/proc/cpuinfo");
    std::string line;
    int found = 0;
    while (found < 2 && std::getline(cpu, line))
      if (line.rfind("model name", 0) == 0 || line.rfind("flags", 0) == 0) h.add(line), ++found;
  }
  std::vector<fs::path> headers;
  for (const auto& e : fs::recursive_directory_iterator(include_dir / "rbdkit"))
    if (e.is_regular_file()) headers.push_back(e.path());
  std::sort(headers.begin(), headers.end());
  for (const fs::path& p : headers) {
    h.add(fs::relative(p, include_dir).generic_string());
    h.add(read_file(p));
  }
  return h.hex();
}

// the first lines of the compiler's output, for an error message
std::string head(const std::string& text, int lines) {
  size_t at = 0;
  for (int i = 0; i < lines && at != std::string::npos; ++i) at = text.find('\n', at + 1);
  return at == std::string::npos ? text : text.substr(0, at) + "\n...";
}

// compiles `source` into `library` (through a temporary file beside it, renamed when done, so
// that a concurrent process never loads half a library)
void compile(const std::string& source, const Build& b, const fs::path& include_dir, const fs::path& library) {
  if (fs::create_directories(library.parent_path()))
    ::chmod(library.parent_path().c_str(), 0700);  // (a folder made here: this user's alone)
  const std::string stem = library.string() + ".tmp" + std::to_string(::getpid());
  const std::string src = stem + b.extension, out = stem + ".so", log = stem + ".log";
  {
    std::ofstream f(src);
    f << source;
    if (!f) throw std::runtime_error("specialize: cannot write " + src);
  }
  const std::string& compiler = b.compiler;
  const std::string cmd = compiler_command(compiler) + " " + b.fixed + " " + b.flags + " -I" +
                          quoted(include_dir.string(), "include folder") + " -o " + quoted(out, "cache folder") +
                          " " + quoted(src, "cache folder") + " > " + quoted(log, "cache folder") + " 2>&1";
  const int status = std::system(cmd.c_str());
  const std::string output = read_file(log);
  std::error_code ec;
  fs::remove(src, ec);
  fs::remove(log, ec);
  if (status != 0) {
    fs::remove(out, ec);
    // the shell's 127: the command was not found
    if (WIFEXITED(status) && WEXITSTATUS(status) == 127)
      throw std::runtime_error(b.extension == ".cu"
                                   ? "specialize: no CUDA compiler: '" + compiler +
                                         "' was not found (set CUDACXX, or SpecializeOptions::cuda_compiler)"
                                   : "specialize: no C++ compiler: '" + compiler +
                                         "' was not found (set CXX, or SpecializeOptions::compiler)");
    throw std::runtime_error("specialize: '" + compiler + "' failed to compile the instance:\n" + head(output, 12));
  }
  ::chmod(out.c_str(), 0755);  // (writable by this user alone, whatever the umask: open_instance checks it)
  fs::rename(out, library);
}

// a file this user owns and nobody else may write, in a folder this user owns that not everyone may
// write (loading code that another user can replace would run their code here)
void check_private(const fs::path& p, mode_t not_writable_by) {
  struct stat st;
  if (::stat(p.c_str(), &st) != 0) throw std::runtime_error("specialize: cannot read " + p.string());
  if (st.st_uid != ::geteuid() || (st.st_mode & not_writable_by))
    throw std::runtime_error("specialize: " + p.string() +
                             " is not this user's (owned by another user, or writable by others): not loaded");
}

// the library, loaded (inst->library), once checked to be this user's alone
template <class I> void open_library(const fs::path& library, I& inst) {
  check_private(library.parent_path(), S_IWOTH);
  check_private(library, S_IWGRP | S_IWOTH);
  inst.path = library.string();
  inst.library = dlopen(inst.path.c_str(), RTLD_NOW | RTLD_LOCAL);
  if (!inst.library) throw std::runtime_error(std::string("specialize: cannot load ") + inst.path + ": " + dlerror());
}

// the library's instance for `model`, checked: ABI, the types' layout, the robot's sizes
std::shared_ptr<Instance> open_instance(const fs::path& library, const Model& model) {
  auto inst = std::make_shared<Instance>();
  open_library(library, *inst);
  using DescribeFn = const instance::Description* (*)();
  auto describe = reinterpret_cast<DescribeFn>(dlsym(inst->library, "rbdkit_instance"));
  const instance::Description* d = describe ? describe() : nullptr;
  if (!d || d->abi != instance::kAbi)
    throw std::runtime_error("specialize: " + inst->path + " is not an rbdkit instance of ABI " +
                             std::to_string(instance::kAbi));
  if (d->layout != instance::kLayout)
    throw std::runtime_error("specialize: " + inst->path + " was compiled with other rbdkit headers than this library's");
  if (d->nb != model.nb() || d->nq != model.nq || d->nv != model.nv)
    throw std::runtime_error("specialize: " + inst->path + " is another robot's (nb, nq, nv = " + std::to_string(d->nb) +
                             ", " + std::to_string(d->nq) + ", " + std::to_string(d->nv) + ")");
  inst->kernels.assign(ops::op_table().size(), nullptr);
  for (int i = 0; i < d->n_entries; ++i) {
    const int op = ops::find_op(d->entries[i].name);
    if (op < 0)
      throw std::runtime_error("specialize: " + inst->path + " has an unknown operation " + d->entries[i].name);
    inst->kernels[op] = d->entries[i].run;
  }
  return inst;
}

// the library's CUDA instance for `model`, checked as open_instance, and that it holds the kernels asked for
std::shared_ptr<CudaInstance> open_cuda_instance(const fs::path& library, const Model& model, bool device) {
  auto inst = std::make_shared<CudaInstance>();
  open_library(library, *inst);
  using DescribeFn = const cuda::instance::Description* (*)();
  auto describe = reinterpret_cast<DescribeFn>(dlsym(inst->library, "rbdkit_cuda_instance"));
  const cuda::instance::Description* d = describe ? describe() : nullptr;
  if (!d || d->abi != cuda::instance::kAbi)
    throw std::runtime_error("specialize: " + inst->path + " is not an rbdkit CUDA instance of ABI " +
                             std::to_string(cuda::instance::kAbi));
  if (d->layout != cuda::instance::kLayout)
    throw std::runtime_error("specialize: " + inst->path + " was compiled with other rbdkit headers than this library's");
  inst->description = d;
  const std::string other = cuda_instance_mismatch(*inst, model);
  if (!other.empty()) throw std::runtime_error("specialize: " + inst->path + " " + other);
  if ((d->device != 0) != device)
    throw std::runtime_error("specialize: " + inst->path + (device ? " holds interpret launches, not GPU kernels"
                                                                    : " holds GPU kernels, not interpret launches"));
  inst->f64.assign(ops::op_table().size(), nullptr);
  inst->f32.assign(ops::op_table().size(), nullptr);
  for (int i = 0; i < d->n_ops; ++i) {
    const int op = ops::find_op(d->names[i]);
    if (op < 0) throw std::runtime_error("specialize: " + inst->path + " has an unknown operation " + d->names[i]);
    inst->f64[op] = reinterpret_cast<const void*>(d->f64[i]);
    inst->f32[op] = reinterpret_cast<const void*>(d->f32[i]);
  }
  return inst;
}

// the library of an instance of kind I: the one this process loaded (handles on the same model share
// it), else the cached file, compiled first when there is none; open() loads and checks it
template <class I, class Open>
std::shared_ptr<I> load_cached(const fs::path& library, const std::string& source, const Build& build,
                               const fs::path& include_dir, Open&& open) {
  static std::mutex lock;  // (one per kind)
  static std::map<std::string, std::weak_ptr<I>> loaded;
  std::lock_guard<std::mutex> lk(lock);
  if (auto inst = loaded[library.string()].lock()) return inst;
  if (!fs::is_regular_file(library)) compile(source, build, include_dir, library);
  std::shared_ptr<I> inst = open();
  loaded[library.string()] = inst;
  return inst;
}

std::string robot_stem(const Model& model) {  // the robot's name as a file name
  std::string stem;
  for (char c : model.name) stem += std::isalnum(static_cast<unsigned char>(c)) || c == '_' || c == '-' ? c : '_';
  return stem.empty() ? "robot" : stem.substr(0, 40);
}

fs::path checked_include_dir(const SpecializeOptions& options) {
  const fs::path include_dir = options.include_dir.empty() ? fs::path(RBDKIT_SOURCE_INCLUDE_DIR)
                                                           : fs::path(options.include_dir);
  if (include_dir.empty() || !fs::is_regular_file(include_dir / "rbdkit" / "codegen" / "instance.hpp"))
    throw std::runtime_error("specialize: rbdkit's headers are not in '" + include_dir.string() +
                             "' (SpecializeOptions::include_dir: the folder holding rbdkit/)");
  return include_dir;
}

std::string cxx_compiler(const SpecializeOptions& options) {
  return !options.compiler.empty() ? options.compiler : !env("CXX").empty() ? env("CXX") : "c++";
}

std::string nvcc_compiler(const SpecializeOptions& options) {
  if (!options.cuda_compiler.empty()) return options.cuda_compiler;
  if (!env("CUDACXX").empty()) return env("CUDACXX");
  if (output_of("command -v nvcc").find("nvcc") != std::string::npos) return "nvcc";
  return "/usr/local/cuda/bin/nvcc";
}

}  // namespace

std::string instance_source(const Model& model) {
  return generate_header(model, kStructName, "a compiled instance (Handle::specialize)") +
         "\n#include \"rbdkit/codegen/instance.hpp\"\n\nRBDKIT_INSTANCE(rbdkit_generated::" + kStructName + ")\n";
}

std::shared_ptr<const Instance> load_instance(const Model& model, const SpecializeOptions& options) {
  if (model.nb() == 0) throw std::runtime_error("specialize: the model has no moving body");
  const fs::path include_dir = checked_include_dir(options);
  const Build build{cxx_compiler(options), kFixedFlags, options.flags, ".cpp"};
  const std::string source = instance_source(model);
  const std::string key = cache_key(source, build, include_dir, "");
  const fs::path library = cache_folder(options) / (robot_stem(model) + "-" + key + ".so");
  return load_cached<Instance>(library, source, build, include_dir, [&] { return open_instance(library, model); });
}

std::string cuda_instance_source(const Model& model) {
  return generate_header(model, kStructName, "a compiled CUDA instance (Handle::specialize, backend='cuda')") +
         "\n#include \"rbdkit/cuda/instance.cuh\"\n\nRBDKIT_CUDA_INSTANCE(rbdkit_generated::" + kStructName + ")\n";
}

std::shared_ptr<const CudaInstance> load_cuda_instance(const Model& model, const SpecializeOptions& options,
                                                       bool device, const std::string& device_key) {
  if (model.nb() == 0) throw std::runtime_error("specialize: the model has no moving body");
  if (device && device_key.empty())
    throw std::invalid_argument("load_cuda_instance: device_key: expected the GPU's name (a key of the cache), got ''");
  // the bodies' __constant__ tables, both dtypes, within the 64 KiB of constant memory (with room for the rest)
  const size_t table_bytes = static_cast<size_t>(model.nb()) * (sizeof(BodyDesc<double>) + sizeof(BodyDesc<float>));
  if (device && table_bytes > 60 * 1024)
    throw std::runtime_error("specialize: the robot's " + std::to_string(model.nb()) + " bodies take " +
                             std::to_string(table_bytes) +
                             " bytes as constant tables, past the GPU's 64 KiB of constant memory: the generic kernels serve it");
  const fs::path include_dir = checked_include_dir(options);
  const Build build = device ? Build{nvcc_compiler(options), kNvccFixedFlags, options.cuda_flags, ".cu"}
                             : Build{cxx_compiler(options), kFixedFlags, options.flags, ".cpp"};
  const std::string source = cuda_instance_source(model);
  const std::string key = cache_key(
      source, build, include_dir,
      "cuda instance " + std::to_string(cuda::instance::kAbi) + (device ? " device " + device_key : " interpret"));
  const fs::path library =
      cache_folder(options) / (robot_stem(model) + (device ? "-cuda-" : "-cuda-interpret-") + key + ".so");
  return load_cached<CudaInstance>(library, source, build, include_dir,
                                   [&] { return open_cuda_instance(library, model, device); });
}

const void* cuda_instance_launch(const CudaInstance& instance, int op, bool f32) {
  const std::vector<const void*>& t = f32 ? instance.f32 : instance.f64;
  return op >= 0 && op < static_cast<int>(t.size()) ? t[op] : nullptr;
}
bool cuda_instance_device(const CudaInstance& instance) { return instance.description->device != 0; }
std::string cuda_instance_mismatch(const CudaInstance& instance, const Model& model) {
  const cuda::instance::Description& d = *instance.description;
  const int general = model.general_path() ? 1 : 0;
  if (d.nb == model.nb() && d.nq == model.nq && d.nv == model.nv && d.has_mimic == general) return "";
  return "is another robot's (nb, nq, nv, general paths = " + std::to_string(d.nb) + ", " + std::to_string(d.nq) +
         ", " + std::to_string(d.nv) + ", " + std::to_string(d.has_mimic) + "; the model's " +
         std::to_string(model.nb()) + ", " + std::to_string(model.nq) + ", " + std::to_string(model.nv) + ", " +
         std::to_string(general) + ")";
}
void cuda_instance_activate(const CudaInstance& instance, int device) {
  char error[512];
  if (instance.description->activate(device, error, sizeof error)) throw std::runtime_error(error);
}
const std::string& instance_path(const CudaInstance& instance) { return instance.path; }

ops::Kernel<double> instance_kernel(const Instance& instance, int op) {
  return op >= 0 && op < static_cast<int>(instance.kernels.size()) ? instance.kernels[op] : nullptr;
}

const std::string& instance_path(const Instance& instance) { return instance.path; }

}  // namespace rbd
