// `totalgrad scenes [--json]`: the scene catalog (core/tasks/scene_catalog.h)
// as a table or as JSON: per scene D, F, state and control names, index sets,
// GP model, costs, defaults and an estimate of a trial's peak memory.
#ifndef TOTALGRAD_CLIENT_CORE_COMMANDS_SCENES_FORMAT_H_
#define TOTALGRAD_CLIENT_CORE_COMMANDS_SCENES_FORMAT_H_

#include <string>

#include <nlohmann/json.hpp>

#include "core/tasks/scene_catalog.h"

namespace totalgrad::cli {

// One object per scene, in catalog order; index sets 0-based.
nlohmann::ordered_json ScenesToJson(const std::vector<tasks::SceneDefinition>& scenes);
// A short text per scene.
std::string ScenesText(const std::vector<tasks::SceneDefinition>& scenes);

}  // namespace totalgrad::cli

#endif  // TOTALGRAD_CLIENT_CORE_COMMANDS_SCENES_FORMAT_H_
