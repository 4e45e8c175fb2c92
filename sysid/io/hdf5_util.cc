#include "sysid/io/hdf5_util.h"

#include <fcntl.h>
#include <sys/mman.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cstdint>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <new>
#include <string>
#include <utility>
#include <vector>

#include "core/text.h"

namespace mjsysid::io::h5 {
namespace {

herr_t InnermostError(unsigned n, const H5E_error2_t* err, void* data) {
  // the upward walk starts at the most specific error
  if (n == 0 && err != nullptr && err->desc != nullptr)
    *static_cast<std::string*>(data) = err->desc;
  return 0;
}

// the most specific message on hdf5's error stack: read it right after the failing call, before
// any other hdf5 call clears the stack
std::string Hdf5Detail() {
  std::string detail;
  H5Ewalk2(H5E_DEFAULT, H5E_WALK_UPWARD, InnermostError, &detail);
  return detail;
}

herr_t CollectAttrName(hid_t, const char* name, const H5A_info_t*, void* data) {
  static_cast<std::vector<std::string>*>(data)->push_back(name);
  return 0;
}

// little-endian unsigned of n bytes (n <= 8)
uint64_t DecodeLE(const unsigned char* p, size_t n) {
  uint64_t v = 0;
  for (size_t i = n; i-- > 0;) v = (v << 8) | p[i];
  return v;
}

// HDF5 1.10's reader of global heap collections (where variable-length strings, such as our
// names attributes, live) trusts the object sizes it finds: an object 0 of size 0 never advances
// its parse loop (the process hangs at 100% CPU), and objects overrunning the collection make it
// read past its buffer. Newer HDF5 releases check this; for 1.10 we walk every collection of the
// file the way HDF5 will, before HDF5 does, and refuse the file when the objects do not tile the
// collection exactly (they always do in a file HDF5 wrote).
void CheckGlobalHeaps(const std::string& path, const std::string& file) {
  const int fd = open(path.c_str(), O_RDONLY | O_CLOEXEC);
  if (fd < 0) return;  // H5Fopen reports it
  struct stat st {};
  if (fstat(fd, &st) != 0 || st.st_size <= 0) {
    close(fd);
    return;
  }
  const auto size = static_cast<size_t>(st.st_size);
  void* map = mmap(nullptr, size, PROT_READ, MAP_PRIVATE, fd, 0);
  close(fd);
  if (map == MAP_FAILED) return;  // H5Fopen reads it or reports it
  struct Unmap {
    void* p;
    size_t n;
    ~Unmap() { munmap(p, n); }
  } unmap{map, size};
  const auto* bytes = static_cast<const unsigned char*>(map);

  // the superblock (at 0, 512, 1024, ...) gives the size of lengths
  static const unsigned char kSignature[8] = {0x89, 'H', 'D', 'F', '\r', '\n', 0x1a, '\n'};
  size_t lengths = 0;
  for (size_t at = 0; at + 16 <= size; at = at == 0 ? 512 : at * 2) {
    if (std::memcmp(bytes + at, kSignature, 8) != 0) continue;
    const unsigned version = bytes[at + 8];
    lengths = version <= 1 ? bytes[at + 14] : bytes[at + 10];
    break;
  }
  if (lengths != 2 && lengths != 4 && lengths != 8) return;  // H5Fopen rejects or copes

  // each collection: "GCOL", version 1, 3 reserved bytes, its size; then objects, each with a
  // header (index u16, references u16, 4 reserved bytes, size) and its data padded to 8 bytes,
  // object 0 (free space) last and unpadded, header included
  const size_t header = 8 + lengths;
  const size_t object_header = 8 + lengths;
  for (const unsigned char* hit = bytes; hit + header <= bytes + size; ++hit) {
    hit = static_cast<const unsigned char*>(
        memmem(hit, static_cast<size_t>(bytes + size - hit), "GCOL", 4));
    if (hit == nullptr || hit + header > bytes + size) break;
    if (hit[4] != 1) continue;  // HDF5 rejects other versions itself
    const uint64_t collection = DecodeLE(hit + 8, lengths);
    const auto offset = static_cast<size_t>(hit - bytes);
    if (collection > size - offset) continue;  // runs past the end: HDF5 fails to read it
    const size_t end = offset + static_cast<size_t>(collection);
    size_t p = offset + header;
    while (p < end) {
      if (p + object_header > end) break;  // too small for an object: free space
      const uint64_t index = DecodeLE(bytes + p, 2);
      const uint64_t object = DecodeLE(bytes + p + 8, lengths);
      const uint64_t need =
          index > 0 ? object_header + ((object + 7) & ~static_cast<uint64_t>(7)) : object;
      if (need == 0 || need > end - p || (index > 0 && object > end - p)) {
        Fail(file, "",
             "corrupt global heap collection at byte " + std::to_string(offset) + ": object " +
                 std::to_string(index) + " at byte " + std::to_string(p) + " has size " +
                 std::to_string(object) + ", which does not fit the collection of " +
                 std::to_string(collection) + " bytes (truncated or corrupt file)");
      }
      p += static_cast<size_t>(need);
    }
  }
}

}  // namespace

// ---------------------------------------------------------------------------------------------
// errors and handles

void Fail(const std::string& file, const std::string& object, const std::string& what) {
  std::string msg = file;
  if (!object.empty()) msg += ": " + object;
  msg += ": " + what;
  throw Error(msg);
}

void FailH5(const std::string& file, const std::string& object, const std::string& what) {
  const std::string detail = Hdf5Detail();
  Fail(file, object, detail.empty() ? what : what + " (HDF5: " + detail + ")");
}

std::mutex& Mutex() {
  static std::mutex mu;
  return mu;
}

void Silence() { H5Eset_auto2(H5E_DEFAULT, nullptr, nullptr); }

Id::Id(Id&& o) noexcept : id_(std::exchange(o.id_, H5I_INVALID_HID)), close_(o.close_) {}

Id& Id::operator=(Id&& o) noexcept {
  if (this != &o) {
    Reset();
    id_ = std::exchange(o.id_, H5I_INVALID_HID);
    close_ = o.close_;
  }
  return *this;
}

bool Id::Close() {
  const herr_t status = id_ >= 0 ? close_(id_) : 0;
  id_ = H5I_INVALID_HID;
  return status >= 0;
}

void Id::Reset() {
  if (id_ >= 0) close_(id_);
  id_ = H5I_INVALID_HID;
}

Id Own(hid_t id, Id::Closer close, const std::string& file, const std::string& object,
       const std::string& what) {
  if (id < 0) FailH5(file, object, what);
  return Id(id, close);
}

void Check(herr_t status, const std::string& file, const std::string& object,
           const std::string& what) {
  if (status < 0) FailH5(file, object, what);
}

Id Utf8Type(const std::string& file, const std::string& object) {
  Id type = Own(H5Tcopy(H5T_C_S1), H5Tclose, file, object, "cannot create a string type");
  Check(H5Tset_size(type.get(), H5T_VARIABLE), file, object, "cannot create a string type");
  Check(H5Tset_cset(type.get(), H5T_CSET_UTF8), file, object, "cannot create a string type");
  return type;
}

Id Utf8Names(hid_t cls, const std::string& file) {
  Id plist = Own(H5Pcreate(cls), H5Pclose, file, "", "cannot create a property list");
  Check(H5Pset_char_encoding(plist.get(), H5T_CSET_UTF8), file, "",
        "cannot set utf-8 name encoding");
  return plist;
}

Id Space1(hsize_t n, const std::string& file, const std::string& object) {
  return Own(H5Screate_simple(1, &n, nullptr), H5Sclose, file, object, "cannot create a dataspace");
}

// ---------------------------------------------------------------------------------------------
// writing

void WriteStringAttr(hid_t obj, const std::string& name, const std::string& value,
                     const std::string& file, const std::string& object) {
  const std::string where = object + " attribute " + Quote(name);
  Id type = Utf8Type(file, where);
  Id space = Own(H5Screate(H5S_SCALAR), H5Sclose, file, where, "cannot create a dataspace");
  Id acpl = Utf8Names(H5P_ATTRIBUTE_CREATE, file);
  Id attr = Own(H5Acreate2(obj, name.c_str(), type.get(), space.get(), acpl.get(), H5P_DEFAULT),
                H5Aclose, file, where, "cannot create attribute");
  const char* ptr = value.c_str();
  Check(H5Awrite(attr.get(), type.get(), &ptr), file, where, "cannot write attribute");
}

void WriteStringArrayAttr(hid_t obj, const std::string& name,
                          const std::vector<std::string>& values, const std::string& file,
                          const std::string& object) {
  const std::string where = object + " attribute " + Quote(name);
  Id type = Utf8Type(file, where);
  Id space = Space1(values.size(), file, where);
  Id attr = Own(H5Acreate2(obj, name.c_str(), type.get(), space.get(), H5P_DEFAULT, H5P_DEFAULT),
                H5Aclose, file, where, "cannot create attribute");
  if (values.empty()) return;
  std::vector<const char*> ptrs;
  for (const std::string& v : values) ptrs.push_back(v.c_str());
  Check(H5Awrite(attr.get(), type.get(), ptrs.data()), file, where, "cannot write attribute");
}

void WriteIntAttr(hid_t obj, const std::string& name, const std::vector<int>& values, bool scalar,
                  const std::string& file, const std::string& object) {
  const std::string where = object + " attribute " + Quote(name);
  Id space = scalar ? Own(H5Screate(H5S_SCALAR), H5Sclose, file, where, "cannot create a dataspace")
                    : Space1(values.size(), file, where);
  Id attr = Own(H5Acreate2(obj, name.c_str(), H5T_STD_I32LE, space.get(), H5P_DEFAULT, H5P_DEFAULT),
                H5Aclose, file, where, "cannot create attribute");
  if (values.empty()) return;
  Check(H5Awrite(attr.get(), H5T_NATIVE_INT, values.data()), file, where, "cannot write attribute");
}

Id WriteDataset(hid_t group, const char* name, const double* data, int rank, const hsize_t* dims,
                const std::string& file, const std::string& object) {
  Id space = Own(H5Screate_simple(rank, dims, nullptr), H5Sclose, file, object,
                 "cannot create a dataspace");
  // no modification times: the same content gives the same bytes
  Id dcpl = Own(H5Pcreate(H5P_DATASET_CREATE), H5Pclose, file, object, "cannot create a plist");
  Check(H5Pset_obj_track_times(dcpl.get(), false), file, object, "cannot set dataset properties");
  Id dset = Own(
      H5Dcreate2(group, name, H5T_IEEE_F64LE, space.get(), H5P_DEFAULT, dcpl.get(), H5P_DEFAULT),
      H5Dclose, file, object, "cannot create dataset");
  hsize_t count = 1;
  for (int i = 0; i < rank; ++i) count *= dims[i];
  if (count > 0) {
    Check(H5Dwrite(dset.get(), H5T_NATIVE_DOUBLE, H5S_ALL, H5S_ALL, H5P_DEFAULT, data), file,
          object, "cannot write dataset");
  }
  return dset;
}

Id CreateGroup(hid_t parent, const std::string& name, bool track_order, const std::string& file,
               const std::string& object) {
  Id lcpl = Utf8Names(H5P_LINK_CREATE, file);
  Id gcpl = Own(H5Pcreate(H5P_GROUP_CREATE), H5Pclose, file, object, "cannot create a plist");
  Check(H5Pset_obj_track_times(gcpl.get(), false), file, object, "cannot set group properties");
  if (track_order) {
    Check(H5Pset_link_creation_order(gcpl.get(), H5P_CRT_ORDER_TRACKED | H5P_CRT_ORDER_INDEXED),
          file, object, "cannot set link creation order");
  }
  return Own(H5Gcreate2(parent, name.c_str(), lcpl.get(), gcpl.get(), H5P_DEFAULT), H5Gclose, file,
             object, "cannot create group");
}

Id CreateFile(const std::string& tmp, const std::string& file) {
  Id fcpl = Own(H5Pcreate(H5P_FILE_CREATE), H5Pclose, file, "", "cannot create a plist");
  Check(H5Pset_link_creation_order(fcpl.get(), H5P_CRT_ORDER_TRACKED | H5P_CRT_ORDER_INDEXED), file,
        "", "cannot set link creation order");
  return Own(H5Fcreate(tmp.c_str(), H5F_ACC_TRUNC, fcpl.get(), H5P_DEFAULT), H5Fclose, file, "",
             "cannot create temporary file " + tmp);
}

// ---------------------------------------------------------------------------------------------
// reading

Id OpenFile(const std::string& path, const std::string& file) {
  std::error_code ec;
  const auto status = std::filesystem::status(path, ec);
  if (ec || !std::filesystem::exists(status)) Fail(file, "", "no such file");
  if (!std::filesystem::is_regular_file(status)) Fail(file, "", "is not a regular file");
    // signature first: a clear message for files that are not hdf5 at all
#if H5_VERSION_GE(1, 12, 0)
  const htri_t is_hdf5 = H5Fis_accessible(path.c_str(), H5P_DEFAULT);
#else
  const htri_t is_hdf5 = H5Fis_hdf5(path.c_str());
#endif
  if (is_hdf5 < 0) FailH5(file, "", "cannot read the file");
  if (is_hdf5 == 0) Fail(file, "", "is not an HDF5 file");
  CheckGlobalHeaps(path, file);
  return Own(H5Fopen(path.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT), H5Fclose, file, "",
             "cannot open HDF5 file (truncated or corrupt?)");
}

std::vector<std::string> LinkNames(hid_t group, const std::string& file,
                                   const std::string& object) {
  H5G_info_t info;
  Check(H5Gget_info(group, &info), file, object, "cannot read group (corrupt file?)");
  Id gcpl = Own(H5Gget_create_plist(group), H5Pclose, file, object, "cannot read group");
  unsigned order_flags = 0;
  Check(H5Pget_link_creation_order(gcpl.get(), &order_flags), file, object, "cannot read group");
  const H5_index_t index =
      (order_flags & H5P_CRT_ORDER_INDEXED) ? H5_INDEX_CRT_ORDER : H5_INDEX_NAME;
  std::vector<std::string> names;
  for (hsize_t i = 0; i < info.nlinks; ++i) {
    const ssize_t len =
        H5Lget_name_by_idx(group, ".", index, H5_ITER_INC, i, nullptr, 0, H5P_DEFAULT);
    if (len < 0) FailH5(file, object, "cannot list group members (corrupt file?)");
    std::string name(static_cast<size_t>(len) + 1, '\0');
    if (H5Lget_name_by_idx(group, ".", index, H5_ITER_INC, i, name.data(), name.size(),
                           H5P_DEFAULT) < 0) {
      FailH5(file, object, "cannot list group members (corrupt file?)");
    }
    name.resize(static_cast<size_t>(len));
    names.push_back(name);
  }
  return names;
}

bool HasLink(hid_t group, const std::string& name, const std::string& file,
             const std::string& object) {
  const htri_t exists = H5Lexists(group, name.c_str(), H5P_DEFAULT);
  if (exists < 0) FailH5(file, object, "cannot read group (corrupt file?)");
  return exists > 0;
}

hsize_t Elements(hid_t space, const std::string& file, const std::string& where) {
  const hssize_t n = H5Sget_simple_extent_npoints(space);
  if (n < 0) FailH5(file, where, "cannot read the dataspace");
  return static_cast<hsize_t>(n);
}

std::vector<std::string> ReadStrings(hid_t attr, const std::string& file,
                                     const std::string& where) {
  Id ftype = Own(H5Aget_type(attr), H5Tclose, file, where, "cannot read attribute type");
  if (H5Tget_class(ftype.get()) != H5T_STRING) Fail(file, where, "is not a string attribute");
  Id space = Own(H5Aget_space(attr), H5Sclose, file, where, "cannot read attribute space");
  if (H5Sget_simple_extent_ndims(space.get()) > 1) Fail(file, where, "has rank > 1");
  const hsize_t n = Elements(space.get(), file, where);
  std::vector<std::string> out;
  if (n == 0) return out;
  const htri_t variable = H5Tis_variable_str(ftype.get());
  if (variable < 0) FailH5(file, where, "cannot read attribute type");
  if (variable) {
    // variable length: hdf5 allocates each string; reclaim them whatever happens
    Id mtype = Own(H5Tcopy(H5T_C_S1), H5Tclose, file, where, "cannot create a string type");
    Check(H5Tset_size(mtype.get(), H5T_VARIABLE), file, where, "cannot create a string type");
    Check(H5Tset_cset(mtype.get(), H5Tget_cset(ftype.get())), file, where,
          "cannot create a string type");
    std::vector<char*> ptrs(n, nullptr);
    if (H5Aread(attr, mtype.get(), ptrs.data()) < 0) FailH5(file, where, "cannot read attribute");
    for (char* p : ptrs) out.emplace_back(p ? p : "");
#if H5_VERSION_GE(1, 12, 0)
    H5Treclaim(mtype.get(), space.get(), H5P_DEFAULT, ptrs.data());
#else
    H5Dvlen_reclaim(mtype.get(), space.get(), H5P_DEFAULT, ptrs.data());
#endif
    return out;
  }
  // fixed length: nul-terminated or nul/space padded
  const size_t size = H5Tget_size(ftype.get());
  if (size == 0) FailH5(file, where, "cannot read attribute type");
  const H5T_str_t pad = H5Tget_strpad(ftype.get());
  std::vector<char> buf(n * size);
  if (H5Aread(attr, ftype.get(), buf.data()) < 0) FailH5(file, where, "cannot read attribute");
  for (hsize_t i = 0; i < n; ++i) {
    const char* p = buf.data() + i * size;
    std::string s(p, strnlen(p, size));
    if (pad == H5T_STR_SPACEPAD) s.erase(s.find_last_not_of(' ') + 1);
    out.push_back(s);
  }
  return out;
}

std::vector<long long> ReadInts(hid_t attr, const std::string& file, const std::string& where) {
  Id ftype = Own(H5Aget_type(attr), H5Tclose, file, where, "cannot read attribute type");
  if (H5Tget_class(ftype.get()) != H5T_INTEGER) Fail(file, where, "is not an integer attribute");
  Id space = Own(H5Aget_space(attr), H5Sclose, file, where, "cannot read attribute space");
  if (H5Sget_simple_extent_ndims(space.get()) > 1) Fail(file, where, "has rank > 1");
  std::vector<long long> out(Elements(space.get(), file, where));
  if (!out.empty() && H5Aread(attr, H5T_NATIVE_LLONG, out.data()) < 0) {
    FailH5(file, where, "cannot read attribute");
  }
  return out;
}

Id OpenAttrIfAny(hid_t obj, const char* name, const std::string& file, const std::string& object) {
  const htri_t exists = H5Aexists(obj, name);
  if (exists < 0) FailH5(file, object, "cannot read attributes (corrupt file?)");
  if (!exists) return Id();
  return Own(H5Aopen(obj, name, H5P_DEFAULT), H5Aclose, file, object + " attribute " + Quote(name),
             "cannot open attribute");
}

std::string ReadScalarString(hid_t obj, const char* name, const std::string& file,
                             const std::string& object, const std::string& missing_hint) {
  Id attr = OpenAttrIfAny(obj, name, file, object);
  const std::string where = object + " attribute " + Quote(name);
  if (attr.get() < 0) Fail(file, where, "is missing" + missing_hint);
  std::vector<std::string> v = ReadStrings(attr.get(), file, where);
  if (v.size() != 1) Fail(file, where, "must hold one string, holds " + std::to_string(v.size()));
  return v[0];
}

std::vector<std::string> AttributeNames(hid_t obj, const std::string& file,
                                        const std::string& object) {
  std::vector<std::string> names;
  hsize_t idx = 0;
  Check(H5Aiterate2(obj, H5_INDEX_NAME, H5_ITER_INC, &idx, CollectAttrName, &names), file, object,
        "cannot list attributes (corrupt file?)");
  return names;
}

std::string ShapeText(const std::vector<hsize_t>& dims) {
  std::string s = "(";
  for (size_t i = 0; i < dims.size(); ++i) s += (i ? ", " : "") + std::to_string(dims[i]);
  return s + ")";
}

RowMatrix ToMatrix(const Array& a) {
  RowMatrix m(static_cast<Eigen::Index>(a.dims[0]), static_cast<Eigen::Index>(a.dims[1]));
  if (!a.data.empty()) std::copy(a.data.begin(), a.data.end(), m.data());
  return m;
}

Array ReadArray(hid_t group, const char* name, int rank, const std::string& file,
                const std::string& object, const std::string& rank_hint) {
  Id dset = Own(H5Dopen2(group, name, H5P_DEFAULT), H5Dclose, file, object,
                "cannot open dataset (not a dataset, or corrupt file?)");
  Id type = Own(H5Dget_type(dset.get()), H5Tclose, file, object, "cannot read data type");
  const H5T_class_t cls = H5Tget_class(type.get());
  if (cls != H5T_FLOAT && cls != H5T_INTEGER) Fail(file, object, "must hold numbers (float64)");
  Id space = Own(H5Dget_space(dset.get()), H5Sclose, file, object, "cannot read dataspace");
  const int ndims = H5Sget_simple_extent_ndims(space.get());
  if (ndims < 0) FailH5(file, object, "cannot read dataspace");
  Array out;
  out.dims.resize(static_cast<size_t>(ndims));
  if (ndims > 0 && H5Sget_simple_extent_dims(space.get(), out.dims.data(), nullptr) < 0) {
    FailH5(file, object, "cannot read dataspace");
  }
  if (ndims != rank) {
    Fail(file, object,
         "has rank " + std::to_string(ndims) + " (shape " + ShapeText(out.dims) +
             "), expected rank " + std::to_string(rank) + rank_hint);
  }
  const hsize_t n = Elements(space.get(), file, object);
  // a corrupt dataspace can claim any shape: before allocating, check that the data can be in the
  // file (all of it when stored uncompressed, at most 1000:1 compressed)
  if (n > 0) {
    Id dcpl = Own(H5Dget_create_plist(dset.get()), H5Pclose, file, object,
                  "cannot read dataset properties");
    hsize_t file_size = 0;
    const hid_t fid = H5Iget_file_id(dset.get());
    if (fid >= 0) {
      if (H5Fget_filesize(fid, &file_size) < 0) file_size = 0;
      H5Fclose(fid);
    }
    const int filters = H5Pget_nfilters(dcpl.get());
    const double bytes = static_cast<double>(n) * static_cast<double>(H5Tget_size(type.get()));
    const double room = static_cast<double>(file_size) * (filters > 0 ? 1000.0 : 1.0);
    if (file_size > 0 && H5Pget_external_count(dcpl.get()) <= 0 && bytes > room) {
      char mb[32];
      std::snprintf(mb, sizeof(mb), "%.1f", bytes / 1e6);
      Fail(file, object,
           "shape " + ShapeText(out.dims) + " needs " + mb + " MB, more than a file of " +
               std::to_string(file_size) + " bytes can hold (truncated or corrupt file?)");
    }
  }
  try {
    out.data.resize(n);
  } catch (const std::bad_alloc&) {
    Fail(file, object, "shape " + ShapeText(out.dims) + " is too large (corrupt file?)");
  } catch (const std::length_error&) {
    Fail(file, object, "shape " + ShapeText(out.dims) + " is too large (corrupt file?)");
  }
  if (n > 0 &&
      H5Dread(dset.get(), H5T_NATIVE_DOUBLE, H5S_ALL, H5S_ALL, H5P_DEFAULT, out.data.data()) < 0) {
    FailH5(file, object, "cannot read data (truncated or corrupt file?)");
  }
  return out;
}

}  // namespace mjsysid::io::h5
