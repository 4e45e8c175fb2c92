#include "core/identified_model.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <memory>
#include <stdexcept>

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

  // the model's spec, each value written into its object's element by the kind's writer
  char error[1024] = "";
  SpecPtr spec(mj_parseXML(model_path.c_str(), nullptr, error, sizeof(error)));
  if (!spec) throw ModelLoadError(model_path + ": " + error);
  for (int i = 0; i < params.size(); ++i) {
    const Parameter& p = params[i];
    const ParameterKindInfo& info = p.info();
    mjsElement* element = nullptr;
    if (info.object != mjOBJ_UNKNOWN) {
      element = mjs_findElement(spec.get(), info.object, specs[i].object.c_str());
      if (!element) {
        throw std::logic_error(model_path + ": " + info.object_name() + " '" + specs[i].object +
                               "' compiles but is not in the parsed spec");
      }
    }
    if (!info.write_mjcf(element, *identified, p.id(), p.index(), values[i])) {
      warnings->push_back("parameter '" + p.label() + "' (" + info.name + " " + specs[i].field +
                          ") has no MJCF attribute: not written into the identified model");
    }
  }

  // compile to check, then save at full precision
  mjModel* compiled = nullptr;
  try {
    compiled = mj_compile(spec.get(), nullptr);
  } catch (const MujocoError& e) {
    throw ModelLoadError(model_path + ": identified model does not compile: " + e.what());
  }
  if (!compiled) {
    throw ModelLoadError(model_path +
                         ": identified model does not compile: " + mjs_getError(spec.get()));
  }
  mj_deleteModel(compiled);
  const std::string xml = SaveXml(spec.get(), model_path);

  // the text compiles back to the values
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
    if (check[i].kind() == ParameterKind::kField) continue;  // not written: warned above
    if (std::abs(read[i] - values[i]) > 1e-9 * std::max(1.0, std::abs(values[i]))) {
      warnings->push_back("identified model: '" + check[i].label() + "' reads " +
                          FormatG17(read[i]) + " instead of " + FormatG17(values[i]));
    }
  }
  return xml;
}

}  // namespace mjsysid
