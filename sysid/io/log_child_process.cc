#include "sysid/io/log_child_process.h"

#include <fcntl.h>
#include <poll.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <csignal>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <mutex>
#include <new>
#include <string>

#include "core/asan.h"
#include "sysid/io/hdf5_util.h"

namespace mjsysid::io::internal {
namespace {

// plain binary encoding of a Log for the pipe (same process image on both ends)
void Put(std::string* out, const void* p, size_t n) {
  if (n > 0) out->append(static_cast<const char*>(p), n);  // p is null for empty matrices
}
void PutSize(std::string* out, uint64_t n) { Put(out, &n, sizeof(n)); }
void PutString(std::string* out, const std::string& s) {
  PutSize(out, s.size());
  Put(out, s.data(), s.size());
}
void PutMatrix(std::string* out, const RowMatrix& m) {
  PutSize(out, static_cast<uint64_t>(m.rows()));
  PutSize(out, static_cast<uint64_t>(m.cols()));
  Put(out, m.data(), sizeof(double) * static_cast<size_t>(m.size()));
}

std::string Encode(const Log& log) {
  std::string out;
  PutString(&out, log.sensor_time);
  PutSize(&out, log.attributes.size());
  for (const auto& [k, v] : log.attributes) {
    PutString(&out, k);
    PutString(&out, v);
  }
  PutSize(&out, log.sequences.size());
  for (const Sequence& s : log.sequences) {
    PutString(&out, s.name);
    PutSize(&out, static_cast<uint64_t>(s.time.size()));
    Put(&out, s.time.data(), sizeof(double) * static_cast<size_t>(s.time.size()));
    for (const RowMatrix* m : {&s.ctrl, &s.sensordata, &s.qpos, &s.qvel, &s.act})
      PutMatrix(&out, *m);
    PutSize(&out, s.sensor_names.size());
    for (size_t i = 0; i < s.sensor_names.size(); ++i) {
      PutString(&out, s.sensor_names[i]);
      PutSize(&out, static_cast<uint64_t>(s.sensor_dims[i]));
    }
    PutSize(&out, s.actuator_names.size());
    for (const std::string& a : s.actuator_names) PutString(&out, a);
    PutSize(&out, static_cast<uint64_t>(s.ctrl_time.size()));
    Put(&out, s.ctrl_time.data(), sizeof(double) * static_cast<size_t>(s.ctrl_time.size()));
    PutSize(&out, s.own_times.size());
    for (const auto& [object, times] : s.own_times) {
      PutString(&out, object);
      PutSize(&out, static_cast<uint64_t>(times.size()));
      Put(&out, times.data(), sizeof(double) * static_cast<size_t>(times.size()));
    }
  }
  return out;
}

class Decoder {
 public:
  Decoder(const std::string& in, const std::string& file) : in_(in), file_(file) {}
  void Get(void* p, size_t n) {
    if (n > in_.size() - at_) h5::Fail(file_, "", "internal error: short reply from the reader");
    if (n > 0) std::memcpy(p, in_.data() + at_, n);
    at_ += n;
  }
  uint64_t Size() {
    uint64_t n = 0;
    Get(&n, sizeof(n));
    if (n > in_.size()) h5::Fail(file_, "", "internal error: bad reply from the reader");
    return n;
  }
  std::string String() {
    std::string s(Size(), '\0');
    Get(s.data(), s.size());
    return s;
  }
  RowMatrix Matrix() {
    const auto rows = static_cast<Eigen::Index>(Size());
    const auto cols = static_cast<Eigen::Index>(Size());
    RowMatrix m(rows, cols);
    Get(m.data(), sizeof(double) * static_cast<size_t>(m.size()));
    return m;
  }

 private:
  const std::string& in_;
  const std::string& file_;
  size_t at_ = 0;
};

Log Decode(const std::string& in, const std::string& file) {
  Decoder d(in, file);
  Log log;
  log.sensor_time = d.String();
  for (uint64_t i = 0, n = d.Size(); i < n; ++i) {
    std::string k = d.String();
    log.attributes[k] = d.String();
  }
  log.sequences.resize(d.Size());
  for (Sequence& s : log.sequences) {
    s.name = d.String();
    s.time.resize(static_cast<Eigen::Index>(d.Size()));
    d.Get(s.time.data(), sizeof(double) * static_cast<size_t>(s.time.size()));
    for (RowMatrix* m : {&s.ctrl, &s.sensordata, &s.qpos, &s.qvel, &s.act}) *m = d.Matrix();
    s.sensor_names.resize(d.Size());
    s.sensor_dims.resize(s.sensor_names.size());
    for (size_t i = 0; i < s.sensor_names.size(); ++i) {
      s.sensor_names[i] = d.String();
      s.sensor_dims[i] = static_cast<int>(d.Size());
    }
    s.actuator_names.resize(d.Size());
    for (std::string& a : s.actuator_names) a = d.String();
    s.ctrl_time.resize(static_cast<Eigen::Index>(d.Size()));
    d.Get(s.ctrl_time.data(), sizeof(double) * static_cast<size_t>(s.ctrl_time.size()));
    s.own_times.resize(d.Size());
    for (auto& [object, times] : s.own_times) {
      object = d.String();
      times.resize(static_cast<Eigen::Index>(d.Size()));
      d.Get(times.data(), sizeof(double) * static_cast<size_t>(times.size()));
    }
  }
  return log;
}

bool WriteAll(int fd, const std::string& data) {
  for (size_t at = 0; at < data.size();) {
    const ssize_t n = ::write(fd, data.data() + at, data.size() - at);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) return false;
    at += static_cast<size_t>(n);
  }
  return true;
}

// in the child: the address space may grow by what a log of this size can need, no more (a
// corrupt string length makes HDF5 allocate up to 4 GiB); not under AddressSanitizer, whose
// shadow memory is address space too. True when that cap is the child's limit: false when the
// process already had a lower one (ulimit -v), which then, not the file, bounds the read
bool CapChildMemory(uintmax_t file_size) {
#ifdef MJSYSID_ASAN
  (void)file_size;
  return true;  // no cap, and ASan's allocator fails only on sizes no log can need: corrupt
#else
  long pages = 0;
  if (FILE* f = std::fopen("/proc/self/statm", "r")) {
    if (std::fscanf(f, "%ld", &pages) != 1) pages = 0;
    std::fclose(f);
  }
  if (pages <= 0) return false;
  const auto used = static_cast<rlim_t>(pages) * static_cast<rlim_t>(sysconf(_SC_PAGESIZE));
  const rlim_t room = std::max<rlim_t>(rlim_t{1} << 30, static_cast<rlim_t>(file_size) * 64);
  const rlimit limit{used + room, used + room};
  return setrlimit(RLIMIT_AS, &limit) == 0;
#endif
}

}  // namespace

Log ReadInChildProcess(const std::string& path, Log (*read_locked)(const std::string&)) {
  const std::string& file = path;
  std::lock_guard<std::mutex> lock(h5::Mutex());  // no other thread inside HDF5 at the fork
  std::error_code ec;
  const uintmax_t size = std::filesystem::file_size(path, ec);
  int fds[2];
  if (pipe2(fds, O_CLOEXEC) != 0) return read_locked(path);
  const pid_t pid = fork();
  if (pid < 0) {
    close(fds[0]);
    close(fds[1]);
    return read_locked(path);  // no child: read here
  }
  if (pid == 0) {
    // the child: single-threaded, h5::Mutex() held on the parent's behalf; _exit skips atexit
    // handlers (HDF5's among them) and stdio flushes that belong to the parent
    close(fds[0]);
    const bool capped = CapChildMemory(ec ? 0 : size);
    std::string reply;
    try {
      reply = "L" + Encode(read_locked(path));
    } catch (const h5::Error& e) {
      reply = std::string("E") + e.what();
    } catch (const std::bad_alloc&) {
      // past our cap: the file asks for more than its size can hold; under a lower limit of the
      // process's own: the machine is short of memory ("M": std::bad_alloc in the parent)
      reply = capped ? "E" + file +
                           ": reading it needs more memory than a log of its size can (corrupt "
                           "file?)"
                     : std::string("M");
    } catch (const std::exception& e) {
      // the file named once: the log's own checks (LogError) already begin with it
      const std::string what = e.what();
      reply = "E" + (what.rfind(file + ":", 0) == 0 ? what : file + ": " + what);
    }
    _exit(WriteAll(fds[1], reply) ? 0 : 1);
  }
  close(fds[1]);
  // the reply, within a time that any sane log of this size is read in
  const auto timeout = std::chrono::seconds(120 + static_cast<long>((ec ? 0 : size) / 10'000'000));
  const auto deadline = std::chrono::steady_clock::now() + timeout;
  std::string reply;
  bool timed_out = false;
  char buf[65536];
  for (;;) {
    const auto left = std::chrono::duration_cast<std::chrono::milliseconds>(
        deadline - std::chrono::steady_clock::now());
    pollfd p{fds[0], POLLIN, 0};
    const int ready = left.count() > 0 ? poll(&p, 1, static_cast<int>(left.count())) : 0;
    if (ready < 0 && errno == EINTR) continue;
    if (ready <= 0) {
      timed_out = true;
      break;
    }
    const ssize_t n = ::read(fds[0], buf, sizeof(buf));
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) break;
    reply.append(buf, static_cast<size_t>(n));
  }
  close(fds[0]);
  if (timed_out) kill(pid, SIGKILL);
  int status = 0;
  while (waitpid(pid, &status, 0) < 0 && errno == EINTR) {
  }
  if (timed_out) {
    h5::Fail(file, "",
             "the HDF5 library did not finish reading the file in " +
                 std::to_string(timeout.count()) + " s (corrupt file?)");
  }
  if (WIFSIGNALED(status)) {
    const int sig = WTERMSIG(status);
    h5::Fail(file, "",
             sig == SIGKILL ? std::string("reading it was killed (out of memory?)")
                            : "the HDF5 library crashed reading the file (" +
                                  std::string(strsignal(sig)) + "): it is corrupt");
  }
  if (reply == "M") throw std::bad_alloc();
  if (reply.empty() || (reply[0] != 'L' && reply[0] != 'E')) {
    // e.g. a sanitizer build, whose handler turns the crash into an exit status
    h5::Fail(file, "",
             "reading it ended without a result (exit status " +
                 std::to_string(WIFEXITED(status) ? WEXITSTATUS(status) : -1) +
                 "): the HDF5 library failed on it (corrupt file?)");
  }
  if (reply[0] == 'E') throw h5::Error(reply.substr(1));
  return Decode(reply.substr(1), file);
}

}  // namespace mjsysid::io::internal
