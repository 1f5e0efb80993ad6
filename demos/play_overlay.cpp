// demos/play_overlay.cpp - the play window's overlay (play_overlay.h) with Dear ImGui 1.86 and its GLFW
// and Vulkan backends.
//
// The one fact to know: Dear ImGui's Vulkan backend records into the swapchain's present command
// buffer (render::Swapchain::Overlay): its font texture's upload before the overlay pass of the first
// present, its draw lists inside every pass while shown. Its buffers rotate over the swapchain's
// presents in flight, so a present never rewrites what one still in flight reads.
#include "demos/play_overlay.h"

#include <GLFW/glfw3.h>
#include <backends/imgui_impl_glfw.h>
#include <backends/imgui_impl_vulkan.h>
#include <fmt/format.h>
#include <imgui.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <utility>
#include <vector>

#include "demos/error.h"
#include "demos/play_controls.h"

namespace displace::app {
namespace {

constexpr float overlay_width = 330.0f;            // pixels
constexpr float overlay_margin = 8.0f;             // pixels from the window's top-left corner
constexpr float pending_graph_height = 28.0f;      // pixels, the texels waiting
constexpr float overlay_background_alpha = 0.78f;  // of the window background
constexpr float graph_height = 90.0f;              // pixels, the stages' graph
constexpr std::array<double, 5> loop_choices = {0.0, 5.0, 10.0, 20.0, 60.0};  // ocean loop, seconds (0: none)

void check_imgui_vulkan(VkResult result) {
  if (result != VK_SUCCESS)
    throw runtime_error(fmt::format("the overlay's Vulkan call failed with VkResult {}", int(result)));
}

std::string budget_word(double milliseconds) {
  return std::isfinite(milliseconds) ? fmt::format("{:g} ms", milliseconds) : std::string("unlimited");
}

enum SeriesIndex {
  sim,
  bake,
  upload,
  render_stage,
  frame,
  sim_device,
  bake_device,
  render_device,
  series_count
};
constexpr std::array<const char*, series_count> series_names = {
    "sim", "bake", "upload", "render", "frame", "sim on dev", "bake on dev", "draw on dev"};
constexpr std::array<ImU32, series_count> series_colors = {
    IM_COL32(90, 170, 255, 255),  IM_COL32(255, 170, 60, 255),  IM_COL32(120, 220, 120, 255),
    IM_COL32(220, 120, 255, 255), IM_COL32(240, 240, 240, 255), IM_COL32(90, 170, 255, 150),
    IM_COL32(255, 170, 60, 150),  IM_COL32(220, 120, 255, 150)};

// The rolling graphs' values: a ring of the last frames made.
struct History {
  std::array<std::array<float, overlay_history_frames>, series_count> milliseconds{};
  std::array<float, overlay_history_frames> pending{};
  int next = 0;      // the ring's next slot
  int recorded = 0;  // frames in the ring
  bool device_times = false;

  int first() const { return recorded == overlay_history_frames ? next : 0; }  // the oldest
  int newest() const { return (next + overlay_history_frames - 1) % overlay_history_frames; }
};

// A slider whose value reaches the scene when it is let go (each change remakes the pipeline).
struct SliderDraft {
  int value = 0;
  bool editing = false;
};

}  // namespace

struct PlayOverlay::State {
  explicit State(render::Swapchain& chain) : swapchain(chain) {}
  ~State();
  State(const State&) = delete;
  State& operator=(const State&) = delete;

  render::Swapchain& swapchain;
  VkDevice device = VK_NULL_HANDLE;
  VkDescriptorPool descriptor_pool = VK_NULL_HANDLE;
  bool imgui_context = false, imgui_glfw = false, imgui_vulkan = false;
  bool fonts_uploaded = false;
  bool draw_pending = false;  // build() rendered a draw list the next present records
  History history;
  SliderDraft steps, lag;
  std::string message;
};

// the device idle, the swapchain's hook removed, then Dear ImGui stopped in reverse
PlayOverlay::State::~State() {
  if (device) vkDeviceWaitIdle(device);
  swapchain.set_overlay({});
  if (imgui_vulkan) ImGui_ImplVulkan_Shutdown();
  if (imgui_glfw) ImGui_ImplGlfw_Shutdown();
  if (imgui_context) ImGui::DestroyContext();
  if (descriptor_pool) vkDestroyDescriptorPool(device, descriptor_pool, nullptr);
}

PlayOverlay::PlayOverlay(GLFWwindow* window, render::Swapchain& swapchain)
    : state_(std::make_unique<State>(swapchain)) {
  State& state = *state_;
  const render::Swapchain::Handles handles = swapchain.handles();
  state.device = handles.device;

  // the font texture's one descriptor set
  VkDescriptorPoolSize pool_size{VK_DESCRIPTOR_TYPE_COMBINED_IMAGE_SAMPLER, 1};
  VkDescriptorPoolCreateInfo pool_info{};
  pool_info.sType = VK_STRUCTURE_TYPE_DESCRIPTOR_POOL_CREATE_INFO;
  pool_info.flags = VK_DESCRIPTOR_POOL_CREATE_FREE_DESCRIPTOR_SET_BIT;
  pool_info.maxSets = 1;
  pool_info.poolSizeCount = 1;
  pool_info.pPoolSizes = &pool_size;
  check_imgui_vulkan(vkCreateDescriptorPool(state.device, &pool_info, nullptr, &state.descriptor_pool));

  IMGUI_CHECKVERSION();
  ImGui::CreateContext();
  state.imgui_context = true;
  ImGuiIO& io = ImGui::GetIO();
  io.IniFilename = nullptr;  // no imgui.ini in the working directory
  io.LogFilename = nullptr;
  ImGui::StyleColorsDark();
  // the font atlas is built now (a frame needs it), uploaded by the first present (Overlay::prepare)
  unsigned char* font_pixels = nullptr;
  int font_width = 0, font_height = 0;
  io.Fonts->GetTexDataAsRGBA32(&font_pixels, &font_width, &font_height);
  state.imgui_glfw = ImGui_ImplGlfw_InitForVulkan(window, true);

  ImGui_ImplVulkan_InitInfo info{};
  info.Instance = handles.instance;
  info.PhysicalDevice = handles.physical_device;
  info.Device = handles.device;
  info.QueueFamily = handles.queue_family;
  info.Queue = handles.queue;
  info.DescriptorPool = state.descriptor_pool;
  info.Subpass = 0;
  info.MinImageCount = std::max(handles.present_slots, 2u);
  info.ImageCount = info.MinImageCount;  // its vertex and index buffers: one set per present in flight
  info.MSAASamples = VK_SAMPLE_COUNT_1_BIT;
  info.CheckVkResultFn = check_imgui_vulkan;
  state.imgui_vulkan = ImGui_ImplVulkan_Init(&info, handles.overlay_render_pass);
  if (!state.imgui_glfw || !state.imgui_vulkan)
    throw runtime_error("Dear ImGui could not start on the play window");

  swapchain.set_overlay(render::Swapchain::Overlay{[&state](VkCommandBuffer commands) {
                                                     if (state.fonts_uploaded) return;
                                                     ImGui_ImplVulkan_CreateFontsTexture(commands);
                                                     state.fonts_uploaded = true;
                                                   },
                                                   [&state](VkCommandBuffer commands) {
                                                     if (!state.draw_pending) return;
                                                     ImGui_ImplVulkan_RenderDrawData(ImGui::GetDrawData(),
                                                                                     commands);
                                                     state.draw_pending = false;
                                                   }});
}

PlayOverlay::~PlayOverlay() = default;

void PlayOverlay::add(const pipeline::FrameRecord& record) {
  History& history = state_->history;
  const std::array<double, series_count> milliseconds = {
      record.sim_ms,   record.bake_ms,       record.upload_ms,      record.render_ms,
      record.frame_ms, record.sim_device_ms, record.bake_device_ms, record.render_device_ms};
  for (std::size_t i = 0; i < series_count; ++i)
    history.milliseconds[i][std::size_t(history.next)] = float(milliseconds[i]);
  history.pending[std::size_t(history.next)] = float(record.pending);
  history.device_times = record.sim_on_device || record.bake_on_device;
  history.next = (history.next + 1) % overlay_history_frames;
  history.recorded = std::min(history.recorded + 1, overlay_history_frames);
}

void PlayOverlay::set_message(std::string message) { state_->message = std::move(message); }

bool PlayOverlay::wants_pointer() const { return ImGui::GetIO().WantCaptureMouse; }
bool PlayOverlay::wants_keys() const { return ImGui::GetIO().WantCaptureKeyboard; }

namespace {

// The graph's top: twice the median frame, and at least the budget with room above it (the first
// frames, which make pipelines, and a read-back last one would flatten every other line).
double graph_scale(const History& history, double budget_ms) {
  std::array<float, overlay_history_frames> frames;
  const auto end = std::copy_n(history.milliseconds[frame].begin(), history.recorded, frames.begin());
  const auto middle = frames.begin() + history.recorded / 2;
  std::nth_element(frames.begin(), middle, end);
  const double median = history.recorded > 0 ? double(*middle) : 1.0;
  const double budget = std::isfinite(budget_ms) && budget_ms > 0.0 ? budget_ms * 1.25 : 0.0;
  return std::max({2.0 * median, budget, 1.0});
}

// The stages' rolling graph: a line per stage on one scale, the newest frame at the right, the budget
// and the bake's share of it as red lines, and a legend with the newest values.
void stage_graph(const History& history, double budget_ms, double bake_budget_ms) {
  const double scale = graph_scale(history, budget_ms);
  const int stages_shown = history.device_times ? series_count : frame + 1;
  ImGui::Text("stage times, last %d frames (top %.1f ms)", history.recorded, scale);

  const ImVec2 origin = ImGui::GetCursorScreenPos();
  const ImVec2 size(overlay_width - 16.0f, graph_height);
  ImGui::Dummy(size);
  ImDrawList& draw = *ImGui::GetWindowDrawList();
  draw.AddRectFilled(origin, ImVec2(origin.x + size.x, origin.y + size.y), IM_COL32(10, 14, 20, 200));
  const auto y_of = [&](double milliseconds) {
    return origin.y + size.y - size.y * float(std::clamp(milliseconds / scale, 0.0, 1.0));
  };
  std::array<ImVec2, overlay_history_frames> points;
  for (int i = 0; i < stages_shown; ++i) {
    const auto& values = history.milliseconds[std::size_t(i)];
    for (int k = 0; k < history.recorded; ++k) {
      const int slot = (history.first() + k) % overlay_history_frames;
      const int column = overlay_history_frames - history.recorded + k;
      points[std::size_t(k)] = ImVec2(origin.x + size.x * float(column) / float(overlay_history_frames - 1),
                                      y_of(values[std::size_t(slot)]));
    }
    if (history.recorded > 1)
      draw.AddPolyline(points.data(), history.recorded, series_colors[std::size_t(i)], 0, 1.5f);
  }
  for (double line_ms : {budget_ms, bake_budget_ms}) {
    if (std::isfinite(line_ms) && line_ms > 0.0 && line_ms <= scale) {
      const float y = y_of(line_ms);
      draw.AddLine(ImVec2(origin.x, y), ImVec2(origin.x + size.x, y), IM_COL32(255, 70, 60, 200));
    }
  }

  // the legend, three to a row
  for (int i = 0; i < stages_shown; ++i) {
    if (i % 3 != 0) ImGui::SameLine(float(i % 3) * (size.x / 3.0f) + 8.0f);
    const double newest =
        history.recorded > 0 ? history.milliseconds[std::size_t(i)][std::size_t(history.newest())] : 0.0;
    ImGui::TextColored(ImGui::ColorConvertU32ToFloat4(series_colors[std::size_t(i)]), "%s %.2f",
                       series_names[std::size_t(i)], newest);
  }
}

template <typename Value, std::size_t Count, typename Name>
bool choose(const char* label, Value& value, const std::array<Value, Count>& choices, Name name) {
  bool changed = false;
  if (ImGui::BeginCombo(label, name(value).c_str())) {
    for (const Value& choice : choices) {
      if (ImGui::Selectable(name(choice).c_str(), choice == value) && choice != value) {
        value = choice;
        changed = true;
      }
    }
    ImGui::EndCombo();
  }
  return changed;
}

bool slider_on_release(const char* label, SliderDraft& draft, int& value, int low, int high,
                       const char* format, ImGuiSliderFlags flags = 0) {
  if (!draft.editing) draft.value = value;
  ImGui::SliderInt(label, &draft.value, low, high, format, flags);
  draft.editing = ImGui::IsItemActive();
  if (!ImGui::IsItemDeactivatedAfterEdit() || draft.value == value) return false;
  value = draft.value;
  return true;
}

// The controls: they edit a copy of the scene; true when it changed (sliders: when let go).
bool scene_controls(pipeline::Scene& scene, SliderDraft& steps, SliderDraft& lag) {
  bool changed = false;
  const std::vector<const render::MethodInfo*> methods = play_methods(scene.surface);
  if (ImGui::BeginCombo("method", render::method_info(scene.method).name)) {
    for (const render::MethodInfo* info : methods) {
      if (ImGui::Selectable(info->name, info->method == scene.method) && info->method != scene.method) {
        scene.method = info->method;
        changed = true;
      }
    }
    ImGui::EndCombo();
  }
  changed |=
      slider_on_release("steps", steps, scene.steps, 1, max_play_steps, "%d", ImGuiSliderFlags_Logarithmic);
  changed |= choose("budget", scene.frame_ms, budget_levels, budget_word);
  changed |= slider_on_release("cone lag", lag, scene.cone_lag_frames, 0, pipeline::max_cone_lag_frames,
                               "%d frames");
  constexpr std::array<pipeline::Backend, 3> backends = {pipeline::Backend::automatic, pipeline::Backend::cpu,
                                                         pipeline::Backend::device};
  const auto backend_name = [](pipeline::Backend backend) {
    return std::string(pipeline::backend_word(backend));
  };
  changed |= choose("sim backend", scene.sim_backend, backends, backend_name);
  changed |= choose("bake backend", scene.bake_backend, backends, backend_name);
  ImGui::BeginDisabled(scene.material != render::Material::water);
  changed |= ImGui::Checkbox("foam", &scene.foam);
  ImGui::EndDisabled();
  ImGui::BeginDisabled(scene.source != pipeline::SourceKind::ocean);
  changed |= choose("ocean loop", scene.ocean.loop_seconds, loop_choices, [](double seconds) {
    return seconds > 0.0 ? fmt::format("{:g} s", seconds) : std::string("none");
  });
  ImGui::EndDisabled();
  return changed;
}

}  // namespace

std::optional<pipeline::Scene> PlayOverlay::build(const pipeline::Scene& scene,
                                                  const pipeline::FrameRecord& record,
                                                  double frames_per_second, bool shown, bool live) {
  State& state = *state_;
  ImGui_ImplVulkan_NewFrame();
  ImGui_ImplGlfw_NewFrame();
  ImGui::NewFrame();
  state.draw_pending = false;
  if (!shown) {
    ImGui::EndFrame();  // input is still taken, nothing is drawn
    return std::nullopt;
  }

  ImGui::SetNextWindowPos(ImVec2(overlay_margin, overlay_margin), ImGuiCond_Always);
  ImGui::SetNextWindowSize(ImVec2(overlay_width, 0.0f), ImGuiCond_Always);
  ImGui::SetNextWindowBgAlpha(overlay_background_alpha);
  std::optional<pipeline::Scene> asked;
  if (ImGui::Begin("displace play (H hides)", nullptr,
                   ImGuiWindowFlags_NoMove | ImGuiWindowFlags_NoResize | ImGuiWindowFlags_NoSavedSettings |
                       ImGuiWindowFlags_NoFocusOnAppearing)) {
    ImGui::Text("%s | frame %lld | t %.2f s | %.0f fps", scene.name.c_str(), record.index, record.time,
                frames_per_second);
    const std::string bake_share =
        std::isfinite(record.bake_budget_ms) ? fmt::format("{:.1f} ms", record.bake_budget_ms) : "unlimited";
    ImGui::Text("budget %s (bake %s)%s", budget_word(scene.frame_ms).c_str(), bake_share.c_str(),
                record.overrun ? " | overrun" : "");
    const History& history = state.history;
    stage_graph(history, scene.frame_ms, record.bake_budget_ms);
    const std::string waiting = fmt::format("texels waiting {}", record.pending);
    float most_pending = 1.0f;
    for (float value : history.pending) most_pending = std::max(most_pending, value);
    ImGui::PlotLines("##pending", history.pending.data(), history.recorded, history.first(), waiting.c_str(),
                     0.0f, most_pending * 1.1f, ImVec2(overlay_width - 16.0f, pending_graph_height));
    if (record.cone_lag > 0) {
      ImGui::Text("cone maps %lld frames old, apexes +%.4f", record.cone_lag, double(record.cone_lift));
    } else {
      ImGui::TextUnformatted("cone maps made for this frame's heights");
    }
    ImGui::Text("sim on %s, bake on %s", record.sim_on_device ? "device" : "CPU",
                record.bake_on_device ? "device" : "CPU");
    ImGui::Separator();
    pipeline::Scene edited = scene;
    ImGui::BeginDisabled(!live);
    const bool changed = scene_controls(edited, state.steps, state.lag);
    ImGui::EndDisabled();
    if (!live) ImGui::TextUnformatted("--frames: the scene stays as given");
    if (!state.message.empty()) ImGui::TextWrapped("%s", state.message.c_str());
    if (changed && live) asked = std::move(edited);
  }
  ImGui::End();
  ImGui::Render();
  state.draw_pending = true;
  return asked;
}

}  // namespace displace::app
