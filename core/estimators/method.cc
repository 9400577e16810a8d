#include "core/estimators/method.h"

#include "absl/strings/str_cat.h"
#include "absl/strings/str_join.h"

namespace totalgrad::estimators {

const EnumNames<Method>& MethodNames() {
  static const EnumNames<Method>* names = new EnumNames<Method>{
      {Method::kRp, "RP"},   {Method::kGr, "GR"},   {Method::kLr, "LR"},
      {Method::kTp, "TP"},   {Method::kGlr, "GLR"}, {Method::kGtp, "GTP"},
      {Method::kGtpSn, "GTP+sn"}, {Method::kDel, "DEL"}, {Method::kPilco, "PILCO"}};
  return *names;
}

std::string MethodName(Method method) { return EnumName(MethodNames(), method); }

absl::StatusOr<Method> ParseMethod(absl::string_view name) {
  std::vector<std::string> known;
  for (const auto& [method, text] : MethodNames()) {
    if (text == name) return method;
    known.push_back(text);
  }
  return absl::InvalidArgumentError(
      absl::StrCat("unknown method '", name, "'; known: ", absl::StrJoin(known, ", ")));
}

std::vector<Method> ParticleMethods() {
  std::vector<Method> methods;
  for (const auto& entry : MethodNames())
    if (IsParticleMethod(entry.first)) methods.push_back(entry.first);
  return methods;
}

std::vector<std::string> ParticleMethodNames() {
  std::vector<std::string> names;
  for (const Method m : ParticleMethods()) names.push_back(MethodName(m));
  return names;
}

std::ostream& operator<<(std::ostream& os, Method method) { return os << MethodName(method); }

}  // namespace totalgrad::estimators
