#include "core/identified_model.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <memory>
#include <stdexcept>

#include "core/field_mjcf.h"
#include "core/mujoco_env.h"
#include "core/text.h"

// MuJoCo's XML writer prints 6 significant digits unless told otherwise; its (exported, private)
// precision setter is declared weak so that a MuJoCo without it still links (then the read-back
// check reports the rounding)
extern "C" {
int _mjPRIVATE__get_xml_precision() __attribute__((weak));
void _mjPRIVATE__set_xml_precision(int precision) __attribute__((weak));
}

namespace mjsysid {
namespace {

namespace fs = std::filesystem;

struct SpecDeleter {
  void operator()(mjSpec* s) const { mj_deleteSpec(s); }
};
using SpecPtr = std::unique_ptr<mjSpec, SpecDeleter>;

// the spec's MJCF text at full precision
std::string SaveXml(const mjSpec* spec, const std::string& model_path) {
  const bool full_precision = _mjPRIVATE__get_xml_precision && _mjPRIVATE__set_xml_precision;
  const int saved_precision = full_precision ? _mjPRIVATE__get_xml_precision() : 0;
  if (full_precision) _mjPRIVATE__set_xml_precision(17);
  // a buffer too small makes mj_saveXMLString return the size it needs: then once more
  char error[1024] = "";
  std::string xml(1 << 16, '\0');
  int rc = mj_saveXMLString(spec, xml.data(), static_cast<int>(xml.size()), error, sizeof(error));
  if (rc > 0) {
    xml.assign(static_cast<size_t>(rc) + 1, '\0');
    rc = mj_saveXMLString(spec, xml.data(), static_cast<int>(xml.size()), error, sizeof(error));
  }
  if (full_precision) _mjPRIVATE__set_xml_precision(saved_precision);
  if (rc != 0) {
    throw ModelLoadError(model_path + ": cannot save the identified model as XML: " + error);
  }
  const size_t end = xml.find('\0');
  if (end != std::string::npos) xml.resize(end);
  return xml;
}

// the element of a type whose compiled id (in the spec's last compile) is id; nullptr if none
mjsElement* ElementOf(mjSpec* spec, mjtObj type, int id) {
  for (mjsElement* e = mjs_firstElement(spec, type); e; e = mjs_nextElement(spec, e)) {
    if (mjs_getId(e) == id) return e;
  }
  return nullptr;
}

// Asset paths: the file is saved elsewhere, so mesh, height field, skin and texture files are
// looked up in absolute folders (the model file's folder joined with meshdir/texturedir)
void MakeAssetDirsAbsolute(mjSpec* spec, const std::string& model_path) {
  bool has_files = false;
  for (mjtObj type : {mjOBJ_MESH, mjOBJ_HFIELD, mjOBJ_SKIN, mjOBJ_TEXTURE}) {
    has_files = has_files || mjs_firstElement(spec, type) != nullptr;
  }
  if (!has_files) return;
  const fs::path folder = fs::absolute(fs::path(model_path)).parent_path();
  for (mjString* dir : {spec->compiler.meshdir, spec->compiler.texturedir}) {
    const fs::path written = mjs_getString(dir);
    if (written.is_absolute()) continue;
    mjs_setString(dir, (folder / written).lexically_normal().string().c_str());
  }
}

// Compiler options that rescale or replace inertials (settotalmass, inertiafromgeom="true",
// boundmass, boundinertia, balanceinertia) would change the written values: they are turned off,
// and every body gets its compiled inertial from the identified model written explicitly (a body
// with no mass and inertia keeps none), so no other body changes either
void KeepInertialsAsWritten(mjSpec* spec, const mjModel& identified) {
  mjsCompiler& c = spec->compiler;
  const bool rescales = c.settotalmass > 0 || c.inertiafromgeom == mjINERTIAFROMGEOM_TRUE ||
                        c.boundmass > 0 || c.boundinertia > 0 || c.balanceinertia;
  if (!rescales) return;
  const MjcfWriter write_inertial = ParameterKindInfoOf(ParameterKind::kBodyMass).write_mjcf;
  for (mjsElement* e = mjs_firstElement(spec, mjOBJ_BODY); e; e = mjs_nextElement(spec, e)) {
    const int b = mjs_getId(e);
    if (b <= 0) continue;  // the world, or a body the compiler fused into its parent
    const mjtNum* inertia = identified.body_inertia + 3 * b;
    if (identified.body_mass[b] > 0 || inertia[0] > 0 || inertia[1] > 0 || inertia[2] > 0) {
      write_inertial(e, identified, b, 0, identified.body_mass[b]);
    } else {
      mjs_asBody(e)->explicitinertial = 0;
    }
  }
  c.settotalmass = -1;
  c.inertiafromgeom = mjINERTIAFROMGEOM_AUTO;
  c.boundmass = 0;
  c.boundinertia = 0;
  c.balanceinertia = 0;
}

// compiles the spec (setting the elements' ids), or ModelLoadError
ModelPtr Compile(mjSpec* spec, const std::string& model_path, const char* what) {
  mjModel* m = nullptr;
  try {
    m = mj_compile(spec, nullptr);
  } catch (const MujocoError& e) {
    throw ModelLoadError(model_path + ": " + what + " does not compile: " + e.what());
  }
  if (!m)
    throw ModelLoadError(model_path + ": " + what + " does not compile: " + mjs_getError(spec));
  return ModelPtr(m);
}

// With alignfree, the compiler moves a free body's frame to its inertial frame, so the compiled
// inertial frames are relative to the moved frames, while the text's inertial clause is read in
// the body frame as written. Returns the identified model with every body's inertial frame
// expressed in its written frame: T_written<-moved (the written inertial frame, compiled without
// alignment, times the inverse of the same frame compiled with it) times the identified frame.
ModelPtr InertialsInWrittenFrames(mjSpec* spec, const mjModel& aligned, const mjModel& identified,
                                  const std::string& model_path) {
  ModelPtr out = CopyModel(identified);
  if (!spec->compiler.alignfree) return out;
  spec->compiler.alignfree = 0;
  const ModelPtr written = Compile(spec, model_path, "model");
  spec->compiler.alignfree = 1;
  for (int b = 1; b < out->nbody; ++b) {
    mjtNum inv_pos[3], inv_quat[4], moved_pos[3], moved_quat[4];
    mju_negPose(inv_pos, inv_quat, aligned.body_ipos + 3 * b, aligned.body_iquat + 4 * b);
    mju_mulPose(moved_pos, moved_quat, written->body_ipos + 3 * b, written->body_iquat + 4 * b,
                inv_pos, inv_quat);
    mju_mulPose(out->body_ipos + 3 * b, out->body_iquat + 4 * b, moved_pos, moved_quat,
                identified.body_ipos + 3 * b, identified.body_iquat + 4 * b);
  }
  return out;
}

// the sizes that decide the layout of every array
bool SameSizes(const mjModel& a, const mjModel& b) {
  return a.nq == b.nq && a.nv == b.nv && a.nu == b.nu && a.na == b.na && a.nbody == b.nbody &&
         a.njnt == b.njnt && a.ngeom == b.ngeom && a.nsite == b.nsite && a.nmesh == b.nmesh &&
         a.nmeshvert == b.nmeshvert && a.npair == b.npair && a.ntendon == b.ntendon &&
         a.nwrap == b.nwrap && a.nsensor == b.nsensor && a.nsensordata == b.nsensordata &&
         a.neq == b.neq && a.nhfield == b.nhfield && a.nhfielddata == b.nhfielddata &&
         a.nflex == b.nflex && a.nskin == b.nskin && a.ntex == b.ntex && a.ntexdata == b.ntexdata &&
         a.nmat == b.nmat && a.nkey == b.nkey && a.nnumeric == b.nnumeric &&
         a.nnumericdata == b.nnumericdata && a.ntuple == b.ntuple && a.ntupledata == b.ntupledata &&
         a.nuserdata == b.nuserdata && a.nplugin == b.nplugin;
}

}  // namespace

std::string IdentifiedModelXml(const std::string& model_path,
                               const std::vector<ParameterSpec>& specs,
                               const std::vector<double>& values,
                               std::vector<std::string>* warnings) {
  InstallMujocoHandlers();
  if (specs.size() != values.size()) {
    throw std::invalid_argument("IdentifiedModelXml: " + std::to_string(specs.size()) +
                                " specs but " + std::to_string(values.size()) + " values");
  }
  std::vector<std::string> ignored;
  if (!warnings) warnings = &ignored;

  // the identified compiled model: every value written with the core's writers
  ModelPtr identified = LoadModel(model_path);
  const ParameterSet params(*identified, specs);
  params.Prepare(identified.get());
  DataPtr scratch = MakeData(*identified);
  params.Write(identified.get(), scratch.get(), values.data());

  // the model's spec, compiled once for the elements' ids; asset folders made absolute
  char error[1024] = "";
  SpecPtr spec(mj_parseXML(model_path.c_str(), nullptr, error, sizeof(error)));
  if (!spec) throw ModelLoadError(model_path + ": " + error);
  MakeAssetDirsAbsolute(spec.get(), model_path);
  const ModelPtr compiled = Compile(spec.get(), model_path, "model");
  const ModelPtr to_write =
      InertialsInWrittenFrames(spec.get(), *compiled, *identified, model_path);

  // each value into its object's element, by its kind's (or its array's) writer
  bool all_written = true;
  for (int i = 0; i < params.size(); ++i) {
    const Parameter& p = params[i];
    const MjcfTarget t = MjcfTargetOf(*identified, p, specs[i]);
    mjsElement* element = t.write_mjcf ? ElementOf(spec.get(), t.object, t.id) : nullptr;
    if (t.write_mjcf && !element) {
      throw std::logic_error(model_path + ": " + mju_type2Str(t.object) + " " +
                             std::to_string(t.id) + " compiles but is not in the parsed spec");
    }
    if (!element || !t.write_mjcf(element, *to_write, t.id, t.index, values[i])) {
      all_written = false;
      const std::string what =
          p.kind() == ParameterKind::kField
              ? "field " + specs[i].field + "[" + std::to_string(p.index()) + "]"
              : p.info().name;
      warnings->push_back(
          "parameter '" + p.label() + "' (" + what +
          ") has no MJCF attribute that holds it as fitted: not written into the identified "
          "model");
    }
  }
  KeepInertialsAsWritten(spec.get(), *to_write);

  // compile to check, then save at full precision
  Compile(spec.get(), model_path, "identified model");
  const std::string xml = SaveXml(spec.get(), model_path);

  // the text compiles back to the values, and to the whole fitted model
  ModelPtr back;
  try {
    back = LoadModelFromString(xml);
  } catch (const ModelLoadError& e) {
    warnings->push_back(
        "identified model: its text does not compile on its own, values not "
        "checked (" +
        std::string(e.what()) + ")");
    return xml;
  }
  const ParameterSet check(*back, specs);
  std::vector<double> read(values.size());
  check.Read(*back, read.data());
  for (int i = 0; i < check.size(); ++i) {
    if (std::abs(read[i] - values[i]) > 1e-9 * std::max(1.0, std::abs(values[i]))) {
      if (check[i].kind() == ParameterKind::kField && !all_written) continue;  // warned above
      warnings->push_back("identified model: '" + check[i].label() + "' reads " +
                          FormatG17(read[i]) + " instead of " + FormatG17(values[i]));
    }
  }
  if (all_written) {
    const std::string differ = SameSizes(*back, *identified)
                                   ? DifferingArrays(*identified, *back, 1e-9)
                                   : std::string("the model sizes");
    if (!differ.empty()) {
      warnings->push_back(
          "identified model: compiled from its text, it differs from the fitted model in " +
          differ);
    }
  }
  return xml;
}

std::string DifferingArrays(const mjModel& a, const mjModel& b, double tolerance) {
  std::string out;
  for (const ModelArray& array : ModelArrays(a)) {
    if (!array.is_mjtnum) continue;
    const auto values = [&](const mjModel& m) {
      return *reinterpret_cast<const mjtNum* const*>(reinterpret_cast<const char*>(&m) +
                                                     array.offset);
    };
    const mjtNum* x = values(a);
    const mjtNum* y = values(b);
    bool differs = false;
    double worst = 0;
    for (int i = 0; i < array.size; ++i) {
      if (x[i] == y[i] || (std::isnan(x[i]) && std::isnan(y[i]))) continue;
      const double diff = std::abs(x[i] - y[i]);
      if (!(diff <= tolerance * std::max(1.0, std::abs(x[i])))) {
        differs = true;
        worst = std::isnan(diff) ? diff : std::max(worst, diff);
      }
    }
    if (differs) {
      out += std::string(out.empty() ? "" : ", ") + array.name + " (" + FormatG17(worst) + ")";
    }
  }
  return out;
}

}  // namespace mjsysid
