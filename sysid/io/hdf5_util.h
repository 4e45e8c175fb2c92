// HDF5 and file helpers shared by the HDF5 formats of sysid/io (logs, fit results). Not part of
// the API.
//
// - Every helper throws h5::Error with the message "<file>: <object>: <what>", with HDF5's
//   innermost message appended as " (HDF5: ...)" when an HDF5 call failed; callers turn it into
//   their own error type (LogError, ResultError) at their API boundary.
// - HDF5 is not thread-safe in its default build: every caller holds Mutex() around its HDF5
//   calls and calls Silence() first (no printing of HDF5's error stack).
// - Files are written through sysid/io/atomic_file.h (ReplaceAtomically), which throws FileError.
#pragma once

#include <hdf5.h>

#include <mutex>
#include <stdexcept>
#include <string>
#include <vector>

#include "core/state.h"

namespace mjsysid::io::h5 {

class Error : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

// "<file>: <object>: <what>" (no object part when object is empty)
[[noreturn]] void Fail(const std::string& file, const std::string& object, const std::string& what);

// Fail, with HDF5's innermost message appended: call right after the failing HDF5 call
[[noreturn]] void FailH5(const std::string& file, const std::string& object,
                         const std::string& what);

// the process-wide lock around HDF5 calls
std::mutex& Mutex();

// switches off HDF5's automatic error printing (per thread in thread-safe builds)
void Silence();

// an owned HDF5 identifier, closed by its own close function
class Id {
 public:
  using Closer = herr_t (*)(hid_t);
  Id() = default;
  Id(hid_t id, Closer close) : id_(id), close_(close) {}
  Id(const Id&) = delete;
  Id& operator=(const Id&) = delete;
  Id(Id&& o) noexcept;
  Id& operator=(Id&& o) noexcept;
  ~Id() { Reset(); }

  hid_t get() const { return id_; }

  // closes now; false when HDF5 reports a failure (for files: the final flush failed)
  bool Close();

 private:
  void Reset();
  hid_t id_ = H5I_INVALID_HID;
  Closer close_ = nullptr;
};

// wraps a freshly returned identifier; a negative one fails with `what`
Id Own(hid_t id, Id::Closer close, const std::string& file, const std::string& object,
       const std::string& what);

// fails with `what` when status < 0
void Check(herr_t status, const std::string& file, const std::string& object,
           const std::string& what);

// variable-length utf-8 string type
Id Utf8Type(const std::string& file, const std::string& object);

// property list of class `cls` making link and attribute names utf-8
Id Utf8Names(hid_t cls, const std::string& file);

// 1-D dataspace of n elements (n = 0 allowed)
Id Space1(hsize_t n, const std::string& file, const std::string& object);

// ---------------------------------------------------------------------------------------------
// writing

// a scalar variable-length utf-8 string attribute
void WriteStringAttr(hid_t obj, const std::string& name, const std::string& value,
                     const std::string& file, const std::string& object);

// a 1-D variable-length utf-8 string attribute
void WriteStringArrayAttr(hid_t obj, const std::string& name,
                          const std::vector<std::string>& values, const std::string& file,
                          const std::string& object);

// an int32 attribute: scalar (values holds one) or 1-D
void WriteIntAttr(hid_t obj, const std::string& name, const std::vector<int>& values, bool scalar,
                  const std::string& file, const std::string& object);

// a float64 dataset of the given shape, row-major, without modification times; returns it open
// for attributes
Id WriteDataset(hid_t group, const char* name, const double* data, int rank, const hsize_t* dims,
                const std::string& file, const std::string& object);

// a group without modification times, its links kept in creation order when track_order is set
Id CreateGroup(hid_t parent, const std::string& name, bool track_order, const std::string& file,
               const std::string& object);

// creates `tmp` (truncating), the root keeping its links in creation order
Id CreateFile(const std::string& tmp, const std::string& file);

// ---------------------------------------------------------------------------------------------
// reading

// checks that `path` is a readable HDF5 file and opens it read-only
Id OpenFile(const std::string& path, const std::string& file);

// names of the links in a group, in creation order when the file tracks it, else by name
std::vector<std::string> LinkNames(hid_t group, const std::string& file, const std::string& object);

// whether `group` has a link called `name`
bool HasLink(hid_t group, const std::string& name, const std::string& file,
             const std::string& object);

// number of elements of an attribute or dataset space; scalar counts as 1, null as 0
hsize_t Elements(hid_t space, const std::string& file, const std::string& where);

// a string attribute (scalar or 1-D), variable or fixed length
std::vector<std::string> ReadStrings(hid_t attr, const std::string& file, const std::string& where);

// an integer attribute (scalar or 1-D)
std::vector<long long> ReadInts(hid_t attr, const std::string& file, const std::string& where);

// an attribute of obj when it exists; an invalid Id otherwise
Id OpenAttrIfAny(hid_t obj, const char* name, const std::string& file, const std::string& object);

// a required scalar string attribute; `missing_hint` is appended to "is missing"
std::string ReadScalarString(hid_t obj, const char* name, const std::string& file,
                             const std::string& object, const std::string& missing_hint);

// names of the attributes of obj, by name
std::vector<std::string> AttributeNames(hid_t obj, const std::string& file,
                                        const std::string& object);

// "(2, 3)"
std::string ShapeText(const std::vector<hsize_t>& dims);

// a numeric dataset, as doubles in row-major order
struct Array {
  std::vector<hsize_t> dims;
  std::vector<double> data;
};

// a rank-2 Array as a row-major matrix (dims[0] x dims[1])
RowMatrix ToMatrix(const Array& a);

// reads dataset `name` of `group`, which must have rank `rank`; `rank_hint` follows the expected
// rank in the message otherwise (e.g. " (T samples)")
Array ReadArray(hid_t group, const char* name, int rank, const std::string& file,
                const std::string& object, const std::string& rank_hint = "");

}  // namespace mjsysid::io::h5
