// The security library without DDS: the policy (parsing, refusals), the documents made from it,
// the keystore's certificates and signatures, and the refusals `pmlsm security check` reports.
#include <gtest/gtest.h>
#include <sys/stat.h>

#include <filesystem>
#include <fstream>

#include "pmlsm/security/keystore.hpp"

namespace pmlsm::security {
namespace {

namespace fs = std::filesystem;

PolicyVocabulary vocabulary() {
  return PolicyVocabulary{{"rt/pmlsm/motor_feedback", "rt/pmlsm/force_command", "rt/pmlsm/node_status"},
                          {"plant_sim", "controller", "kalman_estimator", "pmlsm_topic"}};
}

constexpr char kPolicy[] = R"(governance:
  discovery_protection: sign
  metadata_protection: encrypt
  domains: {min: 3, max: 9}
identities:
  plant_sim:
    publish: [/pmlsm/motor_feedback]
    subscribe: [/pmlsm/force_command]
  controller:
    publish: [rt/pmlsm/force_command]
    subscribe: [pmlsm/motor_feedback]
  kalman_estimator:
    subscribe: [/pmlsm/motor_feedback]
  pmlsm_topic:
    subscribe: [/pmlsm/*]
)";

std::string refusal(const std::string& text) {
  try {
    parse_policy(text, "p.yaml", vocabulary());
  } catch (const SecurityError& e) {
    return e.what();
  }
  return "accepted";
}

TEST(SecurityPolicy, ParsesGrantsProtectionAndDomains) {
  const auto p = parse_policy(kPolicy, "p.yaml", vocabulary());
  EXPECT_EQ(p.data_protection, Protection::kEncrypt);
  EXPECT_EQ(p.discovery_protection, Protection::kSign);
  EXPECT_EQ(p.domain_min, 3);
  EXPECT_EQ(p.domain_max, 9);
  ASSERT_EQ(p.grants.size(), 4u);
  const Grant* c = p.find("controller");
  ASSERT_NE(c, nullptr);
  EXPECT_EQ(c->publish, std::vector<std::string>{"rt/pmlsm/force_command"});
  EXPECT_EQ(c->subscribe, std::vector<std::string>{"rt/pmlsm/motor_feedback"});
  EXPECT_EQ(p.find("pmlsm_topic")->subscribe, vocabulary().topics);
  EXPECT_EQ(p.find("evaluator"), nullptr);
}

// A container's identity (its components share one participant) holds the union of its members'
// grants, each topic once; a container names identities only, once each, under a name of its own.
TEST(SecurityPolicy, AContainerIdentityHoldsTheUnionOfItsMembers) {
  const auto p =
      parse_policy(std::string("containers:\n  chain: [plant_sim, controller, kalman_estimator]\n") + kPolicy, "p.yaml",
                   vocabulary());
  const Grant* chain = p.find("chain");
  ASSERT_NE(chain, nullptr);
  EXPECT_EQ(chain->members, (std::vector<std::string>{"plant_sim", "controller", "kalman_estimator"}));
  EXPECT_EQ(chain->publish, (std::vector<std::string>{"rt/pmlsm/motor_feedback", "rt/pmlsm/force_command"}));
  EXPECT_EQ(chain->subscribe, (std::vector<std::string>{"rt/pmlsm/force_command", "rt/pmlsm/motor_feedback"}));
  EXPECT_TRUE(p.find("controller")->members.empty());

  EXPECT_NE(refusal(std::string(kPolicy) + "containers:\n  chain: [plant_sim, intruder]\n")
                .find("containers.chain[1]: 'intruder' is not an identity of identities:"),
            std::string::npos);
  EXPECT_NE(refusal(std::string(kPolicy) + "containers:\n  controller: [plant_sim]\n")
                .find("containers.controller: 'controller' is already an identity"),
            std::string::npos);
  EXPECT_NE(refusal(std::string(kPolicy) + "containers:\n  chain: [plant_sim, plant_sim]\n")
                .find("containers.chain[1]: 'plant_sim' listed twice"),
            std::string::npos);
  EXPECT_NE(refusal(std::string(kPolicy) + "containers:\n  chain: []\n").find("containers.chain: expected a list"),
            std::string::npos);
}

TEST(SecurityPolicy, RefusesUnknownOrDuplicatedItemsNamingThem) {
  EXPECT_NE(refusal("identities:\n  controller:\n    publish: [/pmlsm/forse_command]\n")
                .find("p.yaml:3:15: identities.controller.publish[0]: unknown topic '/pmlsm/forse_command'"),
            std::string::npos);
  EXPECT_NE(refusal("identities:\n  intruder:\n    publish: [/pmlsm/force_command]\n")
                .find("identities.intruder: unknown node identity"),
            std::string::npos);
  EXPECT_NE(
      refusal("identities:\n  controller:\n    publish: [/pmlsm/force_command]\n  controller:\n    subscribe: []\n")
          .find("identities.controller: duplicate key"),
      std::string::npos);
  EXPECT_NE(refusal("identities:\n  controller:\n    pubish: [/pmlsm/force_command]\n")
                .find("identities.controller.pubish: unknown key"),
            std::string::npos);
  EXPECT_NE(refusal("governance:\n  data_protection: rot13\nidentities:\n  controller: {}\n")
                .find("governance.data_protection: 'rot13' is not one of encrypt, sign"),
            std::string::npos);
  EXPECT_NE(
      refusal("governance:\n  domains: {min: 9, max: 3}\nidentities:\n  controller: {}\n").find("0 <= min <= max"),
      std::string::npos);
  EXPECT_NE(refusal("identities:\n  controller:\n    publish: [/pmlsm/force_command, rt/pmlsm/force_command]\n")
                .find("listed twice"),
            std::string::npos);
  EXPECT_NE(refusal("governance: {}\n").find("grants nothing"), std::string::npos);
  EXPECT_NE(refusal("governance:\n  data_protection: sign\nidentities:\n  controller: {}\n")
                .find("governance.data_protection: 'sign' is refused"),
            std::string::npos);
  EXPECT_NE(refusal("governance:\n  data_protection: none\nidentities:\n  controller: {}\n")
                .find("p.yaml:2:20: governance.data_protection: 'none' leaves every payload in clear"),
            std::string::npos);
  EXPECT_NE(refusal("governance:\n  data_protection: none\n  rtps_protection: sign\nidentities:\n  controller: {}\n")
                .find("allowed only with rtps_protection: encrypt"),
            std::string::npos);
}

TEST(SecurityPolicy, PayloadsUnprotectedOnlyInsideEncryptedRtpsMessages) {
  const auto p = parse_policy(
      "governance:\n  data_protection: none\n  metadata_protection: none\n"
      "  rtps_protection: encrypt\nidentities:\n  controller: {}\n",
      "p.yaml", vocabulary());
  const std::string gov = governance_xml(p);
  EXPECT_NE(gov.find("<rtps_protection_kind>ENCRYPT</rtps_protection_kind>"), std::string::npos);
  EXPECT_NE(gov.find("<data_protection_kind>NONE</data_protection_kind>"), std::string::npos);
}

TEST(SecurityPolicy, DocumentsCarryTheGrantAndDenyTheRest) {
  const auto p = parse_policy(kPolicy, "p.yaml", vocabulary());
  const std::string gov = governance_xml(p);
  EXPECT_NE(gov.find("<allow_unauthenticated_participants>false</allow_unauthenticated_participants>"),
            std::string::npos);
  EXPECT_NE(gov.find("<discovery_protection_kind>SIGN</discovery_protection_kind>"), std::string::npos);
  EXPECT_NE(gov.find("<data_protection_kind>ENCRYPT</data_protection_kind>"), std::string::npos);
  EXPECT_NE(gov.find("<metadata_protection_kind>ENCRYPT</metadata_protection_kind>"), std::string::npos);
  EXPECT_NE(gov.find("<min>3</min><max>9</max>"), std::string::npos);
  const std::string perm =
      permissions_xml(p, *p.find("controller"), "CN=controller", {"2026-01-01T00:00:00", "2027-01-01T00:00:00"});
  EXPECT_NE(perm.find("<subject_name>CN=controller</subject_name>"), std::string::npos);
  EXPECT_NE(perm.find("<publish>\n          <topics>\n            <topic>rt/pmlsm/force_command</topic>"),
            std::string::npos);
  EXPECT_EQ(perm.find("motor_feedback</topic>\n          </topics>\n        </publish>"), std::string::npos);
  EXPECT_NE(perm.find("<default>DENY</default>"), std::string::npos);
  // Nothing granted: ROS 2's graph topic alone (implicit_topics.hpp), published and read.
  const Grant none{"kalman_estimator", {}, {}, {}};
  const std::string only_graph = permissions_xml(p, none, "CN=kalman_estimator", {"a", "b"});
  EXPECT_NE(only_graph.find("<publish>\n          <topics>\n            <topic>ros_discovery_info</topic>\n"
                            "          </topics>\n        </publish>"),
            std::string::npos)
      << only_graph;
  EXPECT_NE(only_graph.find("<subscribe>\n          <topics>\n            <topic>ros_discovery_info</topic>\n"
                            "          </topics>\n        </subscribe>"),
            std::string::npos)
      << only_graph;
  EXPECT_EQ(only_graph.find("rt/pmlsm/"), std::string::npos) << only_graph;
}

TEST(SecurityPki, SignaturesVerifyOnlyAgainstTheSigner) {
  const auto ca = make_ca("test CA", {});
  const auto other_ca = make_ca("other CA", {});
  const auto node = make_identity("controller", ca, {});
  const std::string doc = "<dds>grant</dds>\n";
  const std::string signed_doc = sign_smime(doc, ca);
  std::string why;
  // S/MIME carries text with CRLF line ends.
  EXPECT_EQ(verify_smime(signed_doc, ca.cert_pem, why), "<dds>grant</dds>\r\n") << why;
  EXPECT_TRUE(verify_smime(signed_doc, other_ca.cert_pem, why).empty());
  // Signed by an identity issued by the CA: not the CA (the CVE-2023-24010 case).
  EXPECT_TRUE(verify_smime(sign_smime(doc, node), ca.cert_pem, why).empty());
  // One byte of the signed text changed.
  std::string tampered = signed_doc;
  const auto at = tampered.find("grant");
  ASSERT_NE(at, std::string::npos);
  tampered[at] = 'G';
  EXPECT_TRUE(verify_smime(tampered, ca.cert_pem, why).empty());
}

TEST(SecurityPki, CertificatesChainExpireAndNameTheirSubject) {
  const auto ca = make_ca("test CA", {});
  const auto node = make_identity("controller", ca, {});
  std::string why;
  EXPECT_TRUE(verify_certificate(node.cert_pem, ca.cert_pem, why)) << why;
  EXPECT_FALSE(verify_certificate(node.cert_pem, make_ca("other CA", {}).cert_pem, why));
  EXPECT_FALSE(verify_certificate(make_identity("controller", ca, {-7200, -3600}).cert_pem, ca.cert_pem, why));
  EXPECT_NE(why.find("expired"), std::string::npos) << why;
  EXPECT_EQ(subject_name(node.cert_pem), "CN=controller");
  EXPECT_TRUE(key_matches(node.cert_pem, node.key_pem));
  EXPECT_FALSE(key_matches(node.cert_pem, ca.key_pem));
}

class KeystoreTest : public ::testing::Test {
 protected:
  void SetUp() override {
    root_ = fs::temp_directory_path() / ("pmlsm_keystore_test_" + std::to_string(getpid()));
    fs::remove_all(root_);
  }
  void TearDown() override { fs::remove_all(root_); }
  fs::path root_;
};

TEST_F(KeystoreTest, MakesPrivateKeysVerifiableDocumentsAndRefusesTampering) {
  const auto p = parse_policy(kPolicy, "p.yaml", vocabulary());
  const KeystoreLayout ks(root_.string());
  create_keystore(ks, p, {});
  create_identity(ks, p, "controller", {});
  create_identity(ks, p, "plant_sim", {});
  EXPECT_EQ(list_identities(ks), (std::vector<std::string>{"controller", "plant_sim"}));
  for (const auto& key : {ks.identity_key("controller"), ks.identity_ca_key(), ks.permissions_ca_key()}) {
    struct stat st {};
    ASSERT_EQ(::stat(key.c_str(), &st), 0) << key;
    EXPECT_EQ(st.st_mode & 0777, 0600u) << key;
  }
  EXPECT_TRUE(check_identity(ks, "controller").empty());
  EXPECT_THROW(create_keystore(ks, p, {}), SecurityError);               // never over an existing one
  EXPECT_THROW(create_identity(ks, p, "evaluator", {}), SecurityError);  // no grant

  // The permissions file with a topic changed in the signed text.
  std::string signed_doc = read_file(ks.permissions_p7s("controller"), "permissions");
  const auto at = signed_doc.find("force_command");
  ASSERT_NE(at, std::string::npos);
  signed_doc.replace(at, 13, "motor_feedbac");
  std::ofstream(ks.permissions_p7s("controller"), std::ios::trunc) << signed_doc;
  const auto problems = check_identity(ks, "controller");
  ASSERT_EQ(problems.size(), 1u);
  EXPECT_NE(problems[0].find("permissions.p7s"), std::string::npos) << problems[0];

  // Missing file: named.
  fs::remove(ks.identity_key("plant_sim"));
  const auto missing = check_identity(ks, "plant_sim");
  ASSERT_FALSE(missing.empty());
  EXPECT_NE(missing[0].find("private key of 'plant_sim'"), std::string::npos) << missing[0];

  // Rotation: a new key and certificate, documents still valid.
  const std::string old_cert = read_file(ks.identity_cert("controller"), "cert");
  create_identity(ks, p, "controller", {});
  EXPECT_NE(read_file(ks.identity_cert("controller"), "cert"), old_cert);
  EXPECT_TRUE(check_identity(ks, "controller").empty());
}

}  // namespace
}  // namespace pmlsm::security
