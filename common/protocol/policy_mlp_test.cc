#include "common/protocol/policy_mlp.h"

#include <cmath>

#include "gmock/gmock.h"
#include "gtest/gtest.h"

namespace imca {
namespace {

void AddTensor(v1::Policy* policy, const std::string& name, std::vector<int64_t> shape,
               std::vector<float> data) {
  v1::NamedTensor* t = policy->add_tensors();
  t->set_name(name);
  for (int64_t d : shape) t->add_shape(d);
  for (float x : data) t->add_data(x);
}

v1::Policy TwoLayer() {
  v1::Policy policy;
  policy.set_version(3);
  policy.set_architecture(v1::Policy::MLP_TANH);
  policy.set_obs_dim(2);
  policy.set_num_actions(2);
  AddTensor(&policy, "policy.0.weight", {2, 2}, {1, 0, 0, 2});  // h = tanh(x0, 2 x1).
  AddTensor(&policy, "policy.0.bias", {2}, {0, 0});
  AddTensor(&policy, "policy.1.weight", {2, 2}, {1, 0, 0, 1});  // logits = h + (0, 1).
  AddTensor(&policy, "policy.1.bias", {2}, {0, 1});
  return policy;
}

TEST(PolicyMlpTest, MatchesHandComputedSoftmax) {
  auto mlp = PolicyMlp::FromProto(TwoLayer());
  ASSERT_TRUE(mlp.ok()) << mlp.status();
  EXPECT_EQ(mlp->version(), 3);
  const float obs[4] = {0.5f, 0.25f, 0.0f, 0.0f};
  float probs[4];
  mlp->Probabilities(obs, 2, probs);
  const double l0 = std::tanh(0.5), l1 = std::tanh(0.5) + 1.0;
  EXPECT_NEAR(probs[0], std::exp(l0) / (std::exp(l0) + std::exp(l1)), 1e-6);
  EXPECT_NEAR(probs[0] + probs[1], 1.0, 1e-6);
  EXPECT_NEAR(probs[2], 1.0 / (1.0 + std::exp(1.0)), 1e-6);
}

TEST(PolicyMlpTest, LayerNormArchitectureMatchesHandComputation) {
  // input_norm(gain 1, shift 0) -> W0 = I -> tanh -> norm(gain (2, 1), shift (0, 0.5)) -> W1 = I.
  v1::Policy policy = TwoLayer();
  policy.set_architecture(v1::Policy::MLP_TANH_LAYERNORM);
  AddTensor(&policy, "policy.input_norm.weight", {2}, {1, 1});
  AddTensor(&policy, "policy.input_norm.bias", {2}, {0, 0});
  policy.mutable_tensors(0)->set_data(3, 1.0f);  // W0 = I.
  AddTensor(&policy, "policy.0.norm.weight", {2}, {2, 1});
  AddTensor(&policy, "policy.0.norm.bias", {2}, {0, 0.5});
  auto mlp = PolicyMlp::FromProto(policy);
  ASSERT_TRUE(mlp.ok()) << mlp.status();
  const float obs[2] = {0.5f, 0.25f};
  float probs[2];
  mlp->Probabilities(obs, 1, probs);
  // LN(0.5, 0.25): mean 0.375, var 0.015625 -> +-0.125 / sqrt(0.015625 + 1e-5).
  const double z = 0.125 / std::sqrt(0.015625 + 1e-5);
  const double h = std::tanh(z);  // tanh(z), tanh(-z): mean 0, var h^2.
  const double n = h / std::sqrt(h * h + 1e-5);
  const double l0 = 2 * n + 0.0, l1 = -n + 0.5 + 1.0;  // W1 = I, b1 = (0, 1).
  EXPECT_NEAR(probs[0], std::exp(l0) / (std::exp(l0) + std::exp(l1)), 1e-5);
  policy.mutable_tensors()->RemoveLast();  // policy.0.norm.bias
  EXPECT_EQ(PolicyMlp::FromProto(policy).status().code(), absl::StatusCode::kInvalidArgument);
}

TEST(PolicyMlpTest, ReluArchitectureClampsHiddenUnitsAtZero) {
  v1::Policy policy = TwoLayer();
  policy.set_architecture(v1::Policy::MLP_RELU);
  auto mlp = PolicyMlp::FromProto(policy);
  ASSERT_TRUE(mlp.ok()) << mlp.status();
  // h = relu(-1, 2 * 0.5) = (0, 1); logits = (0, 2).
  const float obs[2] = {-1.0f, 0.5f};
  float probs[2];
  mlp->Probabilities(obs, 1, probs);
  EXPECT_NEAR(probs[0], 1.0 / (1.0 + std::exp(2.0)), 1e-6);
}

TEST(PolicyMlpTest, PerAgentNetworksActOnTheirAgentsRows) {
  // Agent 0's network prefers action 1 by a logit of 3, agent 1's action 0 by 2.
  v1::Policy policy;
  policy.set_architecture(v1::Policy::MLP_RELU);
  policy.set_obs_dim(1);
  policy.set_num_actions(2);
  policy.set_agent_networks(2);
  AddTensor(&policy, "agent0.policy.0.weight", {2, 1}, {0, 0});
  AddTensor(&policy, "agent0.policy.0.bias", {2}, {0, 3});
  AddTensor(&policy, "agent1.policy.0.weight", {2, 1}, {0, 0});
  AddTensor(&policy, "agent1.policy.0.bias", {2}, {2, 0});
  auto mlp = PolicyMlp::FromProto(policy);
  ASSERT_TRUE(mlp.ok()) << mlp.status();
  EXPECT_EQ(mlp->agent_networks(), 2);
  // Rows [env][agent]: two envs of two agents.
  const float obs[4] = {0, 0, 0, 0};
  float probs[8];
  mlp->Probabilities(obs, 4, probs);
  const double p3 = 1.0 / (1.0 + std::exp(-3.0)), p2 = 1.0 / (1.0 + std::exp(-2.0));
  for (int e = 0; e < 2; ++e) {
    EXPECT_NEAR(probs[(e * 2 + 0) * 2 + 1], p3, 1e-6) << e;
    EXPECT_NEAR(probs[(e * 2 + 1) * 2 + 0], p2, 1e-6) << e;
  }
  // Any batch: three rows are agents 0, 1, 0.
  float odd[6] = {-1, -1, -1, -1, -1, -1};
  mlp->Probabilities(obs, 3, odd);
  EXPECT_NEAR(odd[1], p3, 1e-6);
  EXPECT_NEAR(odd[2], p2, 1e-6);
  EXPECT_NEAR(odd[5], p3, 1e-6);
  EXPECT_TRUE(mlp->Fits(1, 2, 2).ok());
  EXPECT_THAT(std::string(mlp->Fits(1, 2, 3).message()), ::testing::HasSubstr("networks for 2 agents"));
  EXPECT_FALSE(mlp->Fits(2, 2, 2).ok());
  policy.mutable_tensors()->RemoveLast();
  EXPECT_FALSE(PolicyMlp::FromProto(policy).ok());  // agent1.policy.0.bias missing.
  policy.set_agent_networks(-1);
  EXPECT_FALSE(PolicyMlp::FromProto(policy).ok());
}

TEST(PolicyMlpTest, RejectsBrokenPolicies) {
  v1::Policy policy = TwoLayer();
  policy.set_architecture(v1::Policy::ARCHITECTURE_UNSPECIFIED);  // E.g. a policy.pb from before the enum.
  EXPECT_EQ(PolicyMlp::FromProto(policy).status().code(), absl::StatusCode::kInvalidArgument);
  EXPECT_THAT(std::string(PolicyMlp::FromProto(policy).status().message()),
              ::testing::HasSubstr("policy.architecture 0 (ARCHITECTURE_UNSPECIFIED) is not MLP_TANH"));
  policy.set_architecture(static_cast<v1::Policy::Architecture>(7));  // A value this build does not know.
  EXPECT_EQ(PolicyMlp::FromProto(policy).status().code(), absl::StatusCode::kInvalidArgument);
  policy = TwoLayer();
  policy.set_num_actions(3);
  EXPECT_EQ(PolicyMlp::FromProto(policy).status().code(), absl::StatusCode::kInvalidArgument);
  policy = TwoLayer();
  policy.mutable_tensors(0)->mutable_data()->RemoveLast();
  EXPECT_EQ(PolicyMlp::FromProto(policy).status().code(), absl::StatusCode::kInvalidArgument);
  policy = TwoLayer();
  policy.mutable_tensors()->DeleteSubrange(3, 1);  // policy.1.bias missing.
  EXPECT_EQ(PolicyMlp::FromProto(policy).status().code(), absl::StatusCode::kInvalidArgument);
}

}  // namespace
}  // namespace imca
