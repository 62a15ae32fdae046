// imca._core: the C++ environments for Python (python/imca/env.py wraps it;
// docs/python.md). The scenarios, the auto-resetting VecEnv and the
// featuriser are the ones the services use, so a Python trainer sees exactly
// what an actor sees. Only the environment library and the renderer are
// linked: no gRPC, no protobuf (the Python protobuf runtime keeps its own
// descriptors), no LibTorch.
//
// Every step writes straight into freshly allocated numpy arrays (no copy
// through a buffer of our own), with the GIL released while C++ runs. Bad
// input raises ValueError or TypeError naming the argument; nothing is
// stepped or changed then.

#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include <cmath>
#include <cstdint>
#include <cstring>
#include <limits>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "absl/strings/str_cat.h"
#include "common/env/env.h"
#include "common/env/featurizer.h"
#include "common/env/vec_env.h"
#include "common/protocol/policy_names.h"
#include "envtool/render.h"

namespace py = pybind11;

namespace imca::python {
namespace {

template <typename T>
using Array = py::array_t<T, py::array::c_style>;

// An array of `shape` (numpy owns the memory).
template <typename T>
Array<T> NewArray(std::vector<py::ssize_t> shape) {
  return Array<T>(std::move(shape));
}

std::string ShapeText(const py::array& a) {
  std::string out = "(";
  for (py::ssize_t i = 0; i < a.ndim(); ++i) absl::StrAppend(&out, i ? ", " : "", a.shape(i));
  return out + (a.ndim() == 1 ? ",)" : ")");
}

std::string ShapeText(const std::vector<py::ssize_t>& shape) {
  std::string out = "(";
  for (size_t i = 0; i < shape.size(); ++i) absl::StrAppend(&out, i ? ", " : "", shape[i]);
  return out + (shape.size() == 1 ? ",)" : ")");
}

// `obj` as an integer numpy array of exactly `shape`: lists and other
// sequences are converted; floats, booleans and objects are refused (no
// silent cast).
py::array IntegerArray(const py::handle& obj, const char* name, const std::vector<py::ssize_t>& shape) {
  py::array a = py::array::ensure(obj);
  if (!a) throw py::type_error(absl::StrCat(name, ": expected an integer array"));
  const char kind = a.dtype().kind();
  if (kind != 'i' && kind != 'u') {
    throw py::type_error(absl::StrCat(name, ": expected an integer array, got dtype ",
                                      std::string(py::str(a.dtype()))));
  }
  bool same = a.ndim() == static_cast<py::ssize_t>(shape.size());
  for (size_t i = 0; same && i < shape.size(); ++i) same = a.shape(i) == shape[i];
  if (!same) {
    throw py::value_error(absl::StrCat(name, ": expected shape ", ShapeText(shape), ", got ", ShapeText(a)));
  }
  return a;
}

// Element `flat` (row-major over the array's shape) of an integer array of
// any width, signedness and strides, as int64 (uint64 values past int64's
// range saturate, so a range check still refuses them).
int64_t IntegerAt(const py::array& a, int64_t flat) {
  const char* p = static_cast<const char*>(a.data());
  for (py::ssize_t d = a.ndim() - 1; d >= 0; --d) {
    const int64_t extent = a.shape(d);
    p += (flat % extent) * a.strides(d);
    flat /= extent;
  }
  const bool is_signed = a.dtype().kind() == 'i';
  switch (a.itemsize()) {
    case 1: return is_signed ? int64_t{*reinterpret_cast<const int8_t*>(p)} : int64_t{*reinterpret_cast<const uint8_t*>(p)};
    case 2: {
      int16_t s; uint16_t u;
      return is_signed ? (std::memcpy(&s, p, 2), int64_t{s}) : (std::memcpy(&u, p, 2), int64_t{u});
    }
    case 4: {
      int32_t s; uint32_t u;
      return is_signed ? (std::memcpy(&s, p, 4), int64_t{s}) : (std::memcpy(&u, p, 4), int64_t{u});
    }
    default: {
      int64_t s; uint64_t u;
      if (is_signed) return (std::memcpy(&s, p, 8), s);
      std::memcpy(&u, p, 8);
      return u > static_cast<uint64_t>(std::numeric_limits<int64_t>::max()) ? std::numeric_limits<int64_t>::max()
                                                                             : static_cast<int64_t>(u);
    }
  }
}

// "name[i, j]" of flat index `flat` in `shape`.
std::string IndexText(const char* name, int64_t flat, const std::vector<py::ssize_t>& shape) {
  std::vector<int64_t> index(shape.size());
  for (size_t d = shape.size(); d-- > 0;) {
    index[d] = flat % shape[d];
    flat /= shape[d];
  }
  std::string out = absl::StrCat(name, "[");
  for (size_t d = 0; d < index.size(); ++d) absl::StrAppend(&out, d ? ", " : "", index[d]);
  return out + "]";
}

// The scenario options of every binary (common/env/scenario_flags.cc), by their
// Python names.
struct Options {
  std::string map;
  int num_agents = 0;
  int step_limit = 0;
  double success_reward = std::nan("");
  double step_penalty = std::nan("");
  int view_radius = 0;
  int door_timer = -1;
  std::string map_dir;  // Empty: env::DefaultMapDir().
};

// E environments of one scenario for Python: a VecEnv (auto-resetting in the
// step, as the actors), the featuriser, and the renderer. Not thread-safe
// (Python callers hold the GIL to enter; the C++ part runs without it, so
// one instance must not be stepped from two threads at once).
class Env {
 public:
  Env(const std::string& scenario, int num_envs, uint64_t seed, const Options& options) : seed_(seed) {
    if (num_envs < 1) throw py::value_error(absl::StrCat("num_envs: must be >= 1, got ", num_envs));
    env::ScenarioConfig config;
    config.name = scenario;
    config.map_path = options.map;
    config.num_agents = options.num_agents;
    config.step_limit = options.step_limit;
    config.success_reward = options.success_reward;
    config.step_penalty = options.step_penalty;
    config.view_radius = options.view_radius;
    config.door_timer = options.door_timer;
    auto made = env::MakeScenario(config, options.map_dir.empty() ? env::DefaultMapDir() : options.map_dir);
    if (!made.ok()) throw py::value_error(std::string(made.status().message()));
    scenario_ = *std::move(made);
    featurizer_ = std::make_unique<env::Featurizer>(*scenario_);
    envs_ = std::make_unique<env::VecEnv>(scenario_.get(), num_envs, seed);
    E_ = num_envs;
    n_ = scenario_->num_agents();
    K_ = scenario_->state_size();
    D_ = featurizer_->obs_dim();
    G_ = featurizer_->global_dim();
    actions_.resize(static_cast<size_t>(E_) * n_);
    finished_.reserve(E_);
  }

  const env::Scenario& scenario() const { return *scenario_; }
  int num_envs() const { return E_; }
  int obs_dim() const { return D_; }
  int global_dim() const { return G_; }
  uint64_t seed() const { return seed_; }

  // Starts a new episode in every env: with `seed`, reseeded (env e from
  // VecEnv::EnvSeed(seed, e)), from a Reset draw or from `states`; without,
  // from the next Reset draw of each env's stream. Returns (obs, info).
  py::tuple Reset(std::optional<uint64_t> seed, const py::object& states) {
    // The first reset of a new env without a seed plays the constructor's
    // seed (as a fresh gymnasium or EnvPool env does).
    if (!seed && !started_) seed = seed_;
    started_ = true;
    if (!states.is_none()) {
      if (!seed) throw py::value_error("states: needs a seed (the draws of the episodes start from it)");
      std::vector<int32_t> given = States(states, "states", {E_, K_});
      envs_->Reseed(*seed, given.data());
    } else if (seed) {
      envs_->Reseed(*seed);
    } else {
      for (int e = 0; e < E_; ++e) envs_->ResetEnv(e);
    }
    if (seed) seed_ = *seed;
    envs_->TakeFinished(&finished_);  // Unfinished episodes end unreported.
    finished_.clear();
    Array<float> obs = NewArray<float>({E_, n_, D_});
    Array<float> global = NewArray<float>({E_, G_});
    {
      py::gil_scoped_release release;
      Featurize(envs_->states(), E_, obs.mutable_data(), global.mutable_data());
    }
    py::dict info = CommonInfo(global);
    return py::make_tuple(obs, info);
  }

  // Steps every env with actions [E, n] (integers in [0, A)). Returns (obs,
  // rewards, terminated, truncated, info); an env whose episode ended is
  // already reset: obs and info["state"] are its next episode's first, and
  // info["final_state"] the state it ended in.
  py::tuple Step(const py::handle& actions_obj) {
    const std::vector<py::ssize_t> shape = {E_, n_};
    py::array actions = IntegerArray(actions_obj, "actions", shape);
    const int64_t count = static_cast<int64_t>(E_) * n_;
    const int64_t a_count = scenario_->num_actions();
    // int32 (read in place) and int64 (numpy's default) C-contiguous arrays
    // are read directly; any other integer layout element by element.
    const bool contiguous = (actions.flags() & py::array::c_style) != 0;
    const bool direct = contiguous && actions.dtype().is(py::dtype::of<int32_t>());
    const int64_t* wide = contiguous && actions.dtype().is(py::dtype::of<int64_t>())
                              ? static_cast<const int64_t*>(actions.data())
                              : nullptr;
    const int32_t* chosen = direct ? static_cast<const int32_t*>(actions.data()) : actions_.data();
    for (int64_t i = 0; i < count; ++i) {
      const int64_t u = direct ? chosen[i] : wide != nullptr ? wide[i] : IntegerAt(actions, i);
      if (u < 0 || u >= a_count) {
        throw py::value_error(absl::StrCat(IndexText("actions", i, shape), " = ", u, " is not in [0, ", a_count,
                                           ")"));
      }
      if (!direct) actions_[i] = static_cast<int32_t>(u);
    }
    started_ = true;
    Array<float> obs = NewArray<float>({E_, n_, D_});
    Array<float> rewards = NewArray<float>({E_, n_});
    Array<bool> terminated = NewArray<bool>({E_});
    Array<bool> truncated = NewArray<bool>({E_});
    Array<int32_t> final_state = NewArray<int32_t>({E_, K_});
    Array<float> global = NewArray<float>({E_, G_});
    Array<int64_t> episode_id = NewArray<int64_t>({E_});
    Array<int32_t> elapsed = NewArray<int32_t>({E_});
    Array<float> episode_return = NewArray<float>({E_});
    Array<bool> success = NewArray<bool>({E_});
    {
      py::gil_scoped_release release;
      int64_t* ids = episode_id.mutable_data();
      for (int e = 0; e < E_; ++e) ids[e] = envs_->episode_id(e);
      envs_->Step(chosen, rewards.mutable_data(), terminated.mutable_data(), truncated.mutable_data(),
                  final_state.mutable_data());
      const int32_t* reached = final_state.data();
      int32_t* t = elapsed.mutable_data();
      for (int e = 0; e < E_; ++e) t[e] = reached[static_cast<size_t>(e) * K_ + scenario_->step_index()];
      float* returns = episode_return.mutable_data();
      bool* won = success.mutable_data();
      std::fill(returns, returns + E_, std::nanf(""));
      std::fill(won, won + E_, false);
      envs_->TakeFinished(&finished_);
      for (const env::EpisodeEnd& end : finished_) {
        returns[end.env] = end.team_return;
        won[end.env] = end.success;
      }
      finished_.clear();
      Featurize(envs_->states(), E_, obs.mutable_data(), global.mutable_data());
    }
    py::dict info = CommonInfo(global);
    info["final_state"] = final_state;
    info["episode_id"] = episode_id;
    info["elapsed_step"] = elapsed;
    info["episode_return"] = episode_return;
    info["success"] = success;
    return py::make_tuple(obs, rewards, terminated, truncated, info);
  }

  // Observations [..., n, D] of compact states [..., K].
  Array<float> Observe(const py::handle& states_obj) const {
    auto [states, lead] = AnyStates(states_obj);
    std::vector<py::ssize_t> shape = lead;
    shape.push_back(n_);
    shape.push_back(D_);
    Array<float> obs = NewArray<float>(shape);
    const int64_t rows = static_cast<int64_t>(states.size()) / K_;
    float* out = obs.mutable_data();
    for (int64_t r = 0; r < rows; ++r) {
      for (int a = 0; a < n_; ++a) featurizer_->Observe(&states[r * K_], a, out + (r * n_ + a) * D_);
    }
    return obs;
  }

  // Global states [..., G] (the critic's input) of compact states [..., K].
  Array<float> GlobalState(const py::handle& states_obj) const {
    auto [states, lead] = AnyStates(states_obj);
    std::vector<py::ssize_t> shape = lead;
    shape.push_back(G_);
    Array<float> global = NewArray<float>(shape);
    const int64_t rows = static_cast<int64_t>(states.size()) / K_;
    for (int64_t r = 0; r < rows; ++r) featurizer_->GlobalState(&states[r * K_], global.mutable_data() + r * G_);
    return global;
  }

  // The current compact states [E, K] (a copy).
  Array<int32_t> CurrentStates() const {
    Array<int32_t> out = NewArray<int32_t>({E_, K_});
    std::memcpy(out.mutable_data(), envs_->states(), sizeof(int32_t) * E_ * K_);
    return out;
  }

  // An RGB picture [H, W, 3] of one compact state [K].
  Array<uint8_t> Render(const py::handle& state_obj, int cell_px) const {
    std::vector<int32_t> state = States(state_obj, "state", {K_});
    auto renderer = envtool::Renderer::Create(scenario_.get(), cell_px);
    if (!renderer.ok()) throw py::value_error(absl::StrCat("cell_px: ", renderer.status().message()));
    const envtool::Image image = renderer->Draw(state.data());
    Array<uint8_t> rgb = NewArray<uint8_t>({image.height, image.width, 3});
    uint8_t* out = rgb.mutable_data();
    for (size_t i = 0; i < image.pixels.size(); ++i) {
      const envtool::Rgb c = envtool::PaletteRgb(image.pixels[i]);
      out[3 * i] = c.r;
      out[3 * i + 1] = c.g;
      out[3 * i + 2] = c.b;
    }
    return rgb;
  }

  // The text picture of one compact state (Scenario::Render).
  std::string Text(const py::handle& state_obj) const {
    std::vector<int32_t> state = States(state_obj, "state", {K_});
    return scenario_->Render(state.data());
  }

 private:
  void Featurize(const int32_t* states, int rows, float* obs, float* global) const {
    for (int r = 0; r < rows; ++r) {
      const int32_t* state = states + static_cast<size_t>(r) * K_;
      for (int a = 0; a < n_; ++a) featurizer_->Observe(state, a, obs + (static_cast<size_t>(r) * n_ + a) * D_);
      featurizer_->GlobalState(state, global + static_cast<size_t>(r) * G_);
    }
  }

  py::dict CommonInfo(const Array<float>& global) const {
    Array<int32_t> env_id = NewArray<int32_t>({E_});
    for (int e = 0; e < E_; ++e) env_id.mutable_data()[e] = e;
    py::dict info;
    info["env_id"] = env_id;
    info["state"] = CurrentStates();
    info["global_state"] = global;
    return info;
  }

  // Compact states of exactly `shape` (last axis K), each checked by
  // Scenario::ValidateState.
  std::vector<int32_t> States(const py::handle& obj, const char* name, const std::vector<py::ssize_t>& shape) const {
    py::array a = IntegerArray(obj, name, shape);
    return CheckedStates(a, name, shape);
  }

  // Compact states of any leading shape [..., K].
  std::pair<std::vector<int32_t>, std::vector<py::ssize_t>> AnyStates(const py::handle& obj) const {
    py::array a = py::array::ensure(obj);
    if (!a || a.ndim() < 1 || a.shape(a.ndim() - 1) != K_) {
      throw py::value_error(absl::StrCat("states: expected shape (..., ", K_, "), the compact state size, got ",
                                         a ? ShapeText(a) : std::string("no array")));
    }
    std::vector<py::ssize_t> shape(a.shape(), a.shape() + a.ndim());
    IntegerArray(a, "states", shape);
    std::vector<int32_t> states = CheckedStates(a, "states", shape);
    shape.pop_back();
    return {std::move(states), shape};
  }

  std::vector<int32_t> CheckedStates(const py::array& a, const char* name,
                                     const std::vector<py::ssize_t>& shape) const {
    const int64_t size = a.size();
    std::vector<int32_t> states(size);
    for (int64_t i = 0; i < size; ++i) {
      const int64_t v = IntegerAt(a, i);
      if (v < std::numeric_limits<int32_t>::min() || v > std::numeric_limits<int32_t>::max()) {
        throw py::value_error(absl::StrCat(IndexText(name, i, shape), " = ", v, " is out of the int32 range"));
      }
      states[i] = static_cast<int32_t>(v);
    }
    for (int64_t r = 0; r * K_ < size; ++r) {
      if (absl::Status valid = scenario_->ValidateState(&states[r * K_]); !valid.ok()) {
        throw py::value_error(absl::StrCat(name, ": state ", r, " (row-major over the leading axes): ",
                                           valid.message()));
      }
    }
    return states;
  }

  uint64_t seed_;
  bool started_ = false;  // Reset or stepped since construction.
  std::unique_ptr<env::Scenario> scenario_;
  std::unique_ptr<env::Featurizer> featurizer_;
  std::unique_ptr<env::VecEnv> envs_;
  int E_ = 0, n_ = 0, K_ = 0, D_ = 0, G_ = 0;
  std::vector<int32_t> actions_;
  std::vector<env::EpisodeEnd> finished_;
};

}  // namespace
}  // namespace imca::python

PYBIND11_MODULE(_core, m) {
  using imca::python::Env;
  using imca::python::Options;
  namespace env = imca::env;
  m.doc() = "The IMCA environments in C++ (use the imca package, not this module).";
  py::class_<Options>(m, "Options")
      .def(py::init<>())
      .def_readwrite("map", &Options::map)
      .def_readwrite("num_agents", &Options::num_agents)
      .def_readwrite("step_limit", &Options::step_limit)
      .def_readwrite("success_reward", &Options::success_reward)
      .def_readwrite("step_penalty", &Options::step_penalty)
      .def_readwrite("view_radius", &Options::view_radius)
      .def_readwrite("door_timer", &Options::door_timer)
      .def_readwrite("map_dir", &Options::map_dir);
  py::class_<Env>(m, "Env")
      .def(py::init<const std::string&, int, uint64_t, const Options&>(), py::arg("scenario"),
           py::arg("num_envs"), py::arg("seed"), py::arg("options"))
      .def("reset", &Env::Reset, py::arg("seed") = py::none(), py::arg("states") = py::none())
      .def("step", &Env::Step, py::arg("actions"))
      .def("observe", &Env::Observe, py::arg("states"))
      .def("global_state", &Env::GlobalState, py::arg("states"))
      .def("states", &Env::CurrentStates)
      .def("render", &Env::Render, py::arg("state"), py::arg("cell_px") = 24)
      .def("text", &Env::Text, py::arg("state"))
      .def_property_readonly("name", [](const Env& e) { return std::string(e.scenario().name()); })
      .def_property_readonly("num_envs", &Env::num_envs)
      .def_property_readonly("num_agents", [](const Env& e) { return e.scenario().num_agents(); })
      .def_property_readonly("num_npcs", [](const Env& e) { return e.scenario().num_npcs(); })
      .def_property_readonly("num_actions", [](const Env& e) { return e.scenario().num_actions(); })
      .def_property_readonly("state_size", [](const Env& e) { return e.scenario().state_size(); })
      .def_property_readonly("obs_dim", &Env::obs_dim)
      .def_property_readonly("global_dim", &Env::global_dim)
      .def_property_readonly("step_limit", [](const Env& e) { return e.scenario().step_limit(); })
      .def_property_readonly("view_radius", [](const Env& e) { return e.scenario().view_radius(); })
      .def_property_readonly("door_timer", [](const Env& e) { return e.scenario().door_timer(); })
      .def_property_readonly("height", [](const Env& e) { return e.scenario().map().height(); })
      .def_property_readonly("width", [](const Env& e) { return e.scenario().map().width(); })
      .def_property_readonly("fingerprint", [](const Env& e) { return e.scenario().fingerprint(); })
      .def_property_readonly("seed", &Env::seed);
  m.def("scenario_names", &env::ScenarioNames);
  m.def("default_map_dir", &env::DefaultMapDir);
  m.def("env_seed", &env::VecEnv::EnvSeed, py::arg("seed"), py::arg("env"),
        "The seed of env `env`'s random stream under `seed` (imca_env --seed plays it).");
  // The policy's tensor names as the learner writes them (common/protocol/policy_names.h).
  m.def("policy_tensor_prefix", &imca::PolicyTensorPrefix, py::arg("agent_networks"), py::arg("k"));
  m.def(
      "layer_tensor_name",
      [](const std::string& prefix, int layer, const std::string& part) {
        return imca::LayerTensorName(prefix, layer, part);
      },
      py::arg("prefix"), py::arg("layer"), py::arg("part"));
  m.def(
      "input_norm_tensor_name",
      [](const std::string& prefix, const std::string& part) { return imca::InputNormTensorName(prefix, part); },
      py::arg("prefix"), py::arg("part"));
}
