// demos/cli/output_flags.cpp - the flags of what a rendering command writes besides its picture and
// of the renderer it draws with (demos/cli/flags.h): --aov, and --device, --validate and
// --pipeline-cache.
#include <filesystem>
#include <string>
#include <vector>

#include "demos/cli/flags.h"
#include "demos/memory.h"

namespace displace::app::cli {

const Words<Aov> aov_words = {
    {"uv", Aov::uv}, {"depth", Aov::depth}, {"iterations", Aov::iterations}, {"fetches", Aov::fetches}};

// --aov NAME=FILE (render) or NAME=PATTERN (sequence, a '#' pattern): uv and depth to .exr,
// iterations and fetches to .exr (raw) or .png (heatmap).
void add_aov_option(CLI::App& app, std::vector<std::string>& aovs, const std::string& description,
                    bool patterns) {
  const std::string value = patterns ? "PATTERN" : "FILE";
  app.add_option("--aov", aovs, description)
      ->type_name("NAME=" + value)
      ->check(text_check([value, patterns](const std::string& text) -> std::string {
        const auto equals = text.find('=');
        if (equals == std::string::npos || equals + 1 == text.size()) {
          return "expects NAME=" + value + " (" + word_list(aov_words, ", ") + "), got " + in_quotes(text);
        }
        if (std::string problem = word_in(aov_words)(text.substr(0, equals)); !problem.empty())
          return problem;
        const Aov aov = word_value(aov_words, text.substr(0, equals));
        std::vector<std::string> extensions{".exr"};
        if (aov == Aov::iterations || aov == Aov::fetches) extensions.push_back(".png");
        const std::string file = text.substr(equals + 1);
        return patterns ? frame_pattern(extensions)(file) : output_file(extensions)(file);
      }))
      ->allow_extra_args(false)
      ->multi_option_policy(CLI::MultiOptionPolicy::TakeAll);
}

std::vector<AovOutput> aov_outputs(const std::vector<std::string>& aovs) {
  std::vector<AovOutput> outputs;
  for (const std::string& aov : aovs) {
    const auto equals = aov.find('=');
    outputs.push_back(
        {word_value(aov_words, aov.substr(0, equals)), std::filesystem::path(aov.substr(equals + 1))});
  }
  return outputs;
}

// --device, --validate and --pipeline-cache, for every command that renders.
void add_renderer_flags(CLI::App& app, render::RendererOptions& options) {
  app.option_defaults()->group("Vulkan");
  add_value(app, "--device", options.device,
            "a device index or part of its name (default: the best GPU, else lavapipe)", "N|NAME",
            not_empty());
  add_switch(app, "--validate", options.validate, "Khronos validation layer; any message fails the command");
  app.add_option(
         "--pipeline-cache", options.pipeline_cache,
         "where compiled pipelines are kept (default $DISPLACE_PIPELINE_CACHE, else ~/.cache/displace)")
      ->type_name("DIR|off")
      ->check(text_check([](const std::string& text) {
        return text.empty() ? std::string("needs a directory or 'off'") : std::string();
      }));
}

void finish_renderer(render::RendererOptions& options) {
  options.memory_limit = memory_limit_from_environment();
  options.memory_limit_source = memory_limit_variable;
}

}  // namespace displace::app::cli
