#include "pmlsm/security/policy.hpp"

#include "pmlsm/security/implicit_topics.hpp"

#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <fstream>
#include <set>
#include <sstream>

namespace pmlsm::security {
namespace {

// Where a node is: "policy.yaml:12:5: identities.controller.publish[2]".
class Located {
 public:
  explicit Located(std::string origin) : origin_(std::move(origin)) {}

  [[noreturn]] void fail(const YAML::Node& node, const std::string& path, const std::string& what) const {
    std::string where = origin_;
    if (node.IsDefined() && node.Mark().line >= 0) {
      where += ":" + std::to_string(node.Mark().line + 1) + ":" + std::to_string(node.Mark().column + 1);
    }
    throw SecurityError(where + ": " + path + ": " + what);
  }

  /// The keys of a mapping in file order, each checked against `allowed` and for duplicates
  /// (yaml-cpp keeps a duplicated key twice instead of refusing it).
  std::vector<std::pair<std::string, YAML::Node>> keys(const YAML::Node& map, const std::string& path,
                                                       const std::vector<std::string>& allowed) const {
    if (!map.IsMap()) fail(map, path, "expected a mapping");
    std::vector<std::pair<std::string, YAML::Node>> out;
    std::set<std::string> seen;
    for (const auto& kv : map) {
      const std::string key = kv.first.Scalar();
      const std::string at = path.empty() ? key : path + "." + key;
      if (!allowed.empty() && std::find(allowed.begin(), allowed.end(), key) == allowed.end()) {
        std::string list;
        for (const auto& a : allowed) list += (list.empty() ? "" : ", ") + a;
        fail(kv.first, at, "unknown key (allowed: " + list + ")");
      }
      if (!seen.insert(key).second) fail(kv.first, at, "duplicate key");
      out.emplace_back(key, kv.second);
    }
    return out;
  }

  std::string scalar(const YAML::Node& node, const std::string& path) const {
    if (!node.IsScalar()) fail(node, path, "expected a single value");
    return node.Scalar();
  }

  int integer(const YAML::Node& node, const std::string& path) const {
    const std::string text = scalar(node, path);
    int value = 0;
    if (!YAML::convert<int>::decode(node, value)) fail(node, path, "expected an integer, got '" + text + "'");
    return value;
  }

 private:
  std::string origin_;
};

Protection parse_protection(const Located& at, const YAML::Node& node, const std::string& path, bool none_allowed) {
  const std::string text = at.scalar(node, path);
  if (text == "encrypt") return Protection::kEncrypt;
  if (text == "sign") return Protection::kSign;
  if (text == "none" && none_allowed) return Protection::kNone;
  at.fail(node, path, "'" + text + "' is not one of " + (none_allowed ? "encrypt, sign, none" : "encrypt, sign"));
}

std::string escape_xml(const std::string& text) {
  std::string out;
  for (const char c : text) {
    switch (c) {
      case '&': out += "&amp;"; break;
      case '<': out += "&lt;"; break;
      case '>': out += "&gt;"; break;
      case '"': out += "&quot;"; break;
      default: out += c;
    }
  }
  return out;
}

void domains_xml(std::ostringstream& out, const Policy& p, const char* indent) {
  out << indent << "<domains>\n"
      << indent << "  <id_range><min>" << p.domain_min << "</min><max>" << p.domain_max << "</max></id_range>\n"
      << indent << "</domains>\n";
}

void topics_xml(std::ostringstream& out, const char* element, const std::vector<std::string>& topics) {
  if (topics.empty()) return;
  out << "        <" << element << ">\n          <topics>\n";
  for (const auto& t : topics) out << "            <topic>" << escape_xml(t) << "</topic>\n";
  out << "          </topics>\n        </" << element << ">\n";
}

}  // namespace

const char* protection_name(Protection p) {
  switch (p) {
    case Protection::kNone: return "NONE";
    case Protection::kSign: return "SIGN";
    case Protection::kEncrypt: return "ENCRYPT";
  }
  return "NONE";
}

const Grant* Policy::find(const std::string& identity) const {
  for (const auto& g : grants) {
    if (g.identity == identity) return &g;
  }
  return nullptr;
}

std::string dds_topic_name(const std::string& name) {
  if (name.rfind("rt/pmlsm/", 0) == 0) return name;
  if (name.rfind("/pmlsm/", 0) == 0) return "rt" + name;
  if (name.rfind("pmlsm/", 0) == 0) return "rt/" + name;
  return name;
}

// The policy file top to bottom, each section checked where it is read; kept in one function
// so a reader follows the file's layout.
// NOLINTNEXTLINE(readability-function-size)
Policy parse_policy(const std::string& yaml_text, const std::string& origin, const PolicyVocabulary& vocabulary) {
  YAML::Node root;
  try {
    root = YAML::Load(yaml_text);
  } catch (const YAML::Exception& e) {
    throw SecurityError(origin + ": not YAML: " + e.what());
  }
  const Located at(origin);
  Policy policy;
  bool have_identities = false;
  YAML::Node data_protection_node;
  YAML::Node containers;
  bool have_containers = false;
  for (const auto& [key, node] : at.keys(root, "", {"governance", "identities", "containers"})) {
    if (key == "containers") {
      containers = node;
      have_containers = true;
      continue;
    }
    if (key == "governance") {
      for (const auto& [gkey, g] : at.keys(node, "governance",
                                           {"data_protection", "metadata_protection", "discovery_protection",
                                            "liveliness_protection", "rtps_protection", "domains"})) {
        const std::string path = "governance." + gkey;
        if (gkey == "data_protection") {
          policy.data_protection = parse_protection(at, g, path, true);
          data_protection_node = g;
          // Measured with Debian's Fast DDS 2.9.1: with payloads only signed (GMAC), every
          // receiver fails "Error decoding encoded payload" and no sample arrives; the metadata
          // protection kind makes no difference. A policy must not make a silent, dead bus.
          if (policy.data_protection == Protection::kSign) {
            at.fail(g, path,
                    "'sign' is refused: Fast DDS 2.9.1 receivers drop every payload that is signed "
                    "without being encrypted (README, Security); use encrypt");
          }
        }
        if (gkey == "metadata_protection") policy.metadata_protection = parse_protection(at, g, path, true);
        if (gkey == "discovery_protection") policy.discovery_protection = parse_protection(at, g, path, false);
        if (gkey == "liveliness_protection") policy.liveliness_protection = parse_protection(at, g, path, false);
        if (gkey == "rtps_protection") policy.rtps_protection = parse_protection(at, g, path, true);
        if (gkey == "domains") {
          bool have_min = false, have_max = false;
          for (const auto& [dkey, d] : at.keys(g, path, {"min", "max"})) {
            (dkey == "min" ? policy.domain_min : policy.domain_max) = at.integer(d, path + "." + dkey);
            (dkey == "min" ? have_min : have_max) = true;
          }
          if (!have_min || !have_max) at.fail(g, path, "needs both min and max");
          if (policy.domain_min < 0 || policy.domain_max > 232 || policy.domain_min > policy.domain_max) {
            at.fail(g, path,
                    "must satisfy 0 <= min <= max <= 232, got " + std::to_string(policy.domain_min) + ".." +
                        std::to_string(policy.domain_max));
          }
        }
      }
    } else {
      have_identities = true;
      for (const auto& [identity, spec] : at.keys(node, "identities", {})) {
        const std::string path = "identities." + identity;
        const auto& known = vocabulary.identities;
        if (std::find(known.begin(), known.end(), identity) == known.end()) {
          std::string list;
          for (const auto& k : known) list += (list.empty() ? "" : ", ") + k;
          at.fail(node, path, "unknown node identity (the known ones: " + list + ")");
        }
        Grant grant{identity, {}, {}, {}};
        for (const auto& [role, topics] : at.keys(spec, path, {"publish", "subscribe"})) {
          const std::string role_path = path + "." + role;
          if (!topics.IsSequence()) at.fail(topics, role_path, "expected a list of topics");
          auto& list = role == "publish" ? grant.publish : grant.subscribe;
          for (std::size_t i = 0; i < topics.size(); ++i) {
            const std::string item_path = role_path + "[" + std::to_string(i) + "]";
            const std::string name = dds_topic_name(at.scalar(topics[i], item_path));
            if (name == "rt/pmlsm/*") {  // every project topic, written out one by one
              if (!list.empty() || topics.size() != 1) at.fail(topics[i], item_path, "'/pmlsm/*' must stand alone");
              list = vocabulary.topics;
              continue;
            }
            if (std::find(vocabulary.topics.begin(), vocabulary.topics.end(), name) == vocabulary.topics.end()) {
              at.fail(topics[i], item_path, "unknown topic '" + topics[i].Scalar() + "'");
            }
            if (std::find(list.begin(), list.end(), name) != list.end()) {
              at.fail(topics[i], item_path, "topic '" + topics[i].Scalar() + "' listed twice");
            }
            list.push_back(name);
          }
        }
        policy.grants.push_back(std::move(grant));
      }
    }
  }
  // Payloads in clear are allowed only inside whole RTPS messages that are encrypted (one
  // AES-GCM operation a datagram instead of one a payload and one a submessage).
  if (policy.data_protection == Protection::kNone && policy.rtps_protection != Protection::kEncrypt) {
    at.fail(data_protection_node, "governance.data_protection",
            "'none' leaves every payload in clear on the wire; it is allowed only with rtps_protection: encrypt");
  }
  if (!have_identities || policy.grants.empty()) at.fail(root, "identities", "the policy grants nothing to anyone");
  // A container's components share one participant (one a process): it authenticates as the
  // container's identity, which holds the union of its members' grants.
  if (have_containers) {
    for (const auto& [name, members] : at.keys(containers, "containers", {})) {
      const std::string path = "containers." + name;
      if (policy.find(name) != nullptr) at.fail(members, path, "'" + name + "' is already an identity");
      if (!members.IsSequence() || members.size() == 0) at.fail(members, path, "expected a list of identities");
      Grant grant{name, {}, {}, {}};
      for (std::size_t i = 0; i < members.size(); ++i) {
        const std::string item_path = path + "[" + std::to_string(i) + "]";
        const std::string member = at.scalar(members[i], item_path);
        const Grant* g = policy.find(member);
        if (g == nullptr || !g->members.empty()) {
          at.fail(members[i], item_path, "'" + member + "' is not an identity of identities:");
        }
        if (std::find(grant.members.begin(), grant.members.end(), member) != grant.members.end()) {
          at.fail(members[i], item_path, "'" + member + "' listed twice");
        }
        grant.members.push_back(member);
        for (const auto& t : g->publish) {
          if (std::find(grant.publish.begin(), grant.publish.end(), t) == grant.publish.end())
            grant.publish.push_back(t);
        }
        for (const auto& t : g->subscribe) {
          if (std::find(grant.subscribe.begin(), grant.subscribe.end(), t) == grant.subscribe.end()) {
            grant.subscribe.push_back(t);
          }
        }
      }
      policy.grants.push_back(std::move(grant));
    }
  }
  return policy;
}

Policy load_policy(const std::string& path, const PolicyVocabulary& vocabulary) {
  std::ifstream in(path);
  if (!in) throw SecurityError("cannot read the security policy '" + path + "'");
  std::ostringstream text;
  text << in.rdbuf();
  return parse_policy(text.str(), path, vocabulary);
}

std::string governance_xml(const Policy& p) {
  std::ostringstream out;
  out << "<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n"
      << "<!-- Generated by `pmlsm security` from the security policy: do not edit (the signature would break). -->\n"
      << "<dds xmlns:xsi=\"http://www.w3.org/2001/XMLSchema-instance\"\n"
      << "     "
         "xsi:noNamespaceSchemaLocation=\"http://www.omg.org/spec/DDS-SECURITY/20170901/"
         "omg_shared_ca_governance.xsd\">\n"
      << "  <domain_access_rules>\n"
      << "    <domain_rule>\n";
  domains_xml(out, p, "      ");
  out << "      <allow_unauthenticated_participants>false</allow_unauthenticated_participants>\n"
      << "      <enable_join_access_control>true</enable_join_access_control>\n"
      << "      <discovery_protection_kind>" << protection_name(p.discovery_protection)
      << "</discovery_protection_kind>\n"
      << "      <liveliness_protection_kind>" << protection_name(p.liveliness_protection)
      << "</liveliness_protection_kind>\n"
      << "      <rtps_protection_kind>" << protection_name(p.rtps_protection) << "</rtps_protection_kind>\n"
      << "      <topic_access_rules>\n"
      << "        <topic_rule>\n"
      << "          <topic_expression>*</topic_expression>\n"
      << "          <enable_discovery_protection>true</enable_discovery_protection>\n"
      << "          <enable_liveliness_protection>true</enable_liveliness_protection>\n"
      << "          <enable_read_access_control>true</enable_read_access_control>\n"
      << "          <enable_write_access_control>true</enable_write_access_control>\n"
      << "          <metadata_protection_kind>" << protection_name(p.metadata_protection)
      << "</metadata_protection_kind>\n"
      << "          <data_protection_kind>" << protection_name(p.data_protection) << "</data_protection_kind>\n"
      << "        </topic_rule>\n"
      << "      </topic_access_rules>\n"
      << "    </domain_rule>\n"
      << "  </domain_access_rules>\n"
      << "</dds>\n";
  return out.str();
}

std::string permissions_xml(const Policy& p, const Grant& g, const std::string& subject_name,
                            const Validity& validity) {
  std::ostringstream out;
  out << "<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n"
      << "<!-- Generated by `pmlsm security` from the security policy: do not edit (the signature would break). -->\n"
      << "<dds xmlns:xsi=\"http://www.w3.org/2001/XMLSchema-instance\"\n"
      << "     "
         "xsi:noNamespaceSchemaLocation=\"http://www.omg.org/spec/DDS-SECURITY/20170901/"
         "omg_shared_ca_permissions.xsd\">\n"
      << "  <permissions>\n"
      << "    <grant name=\"" << escape_xml(g.identity) << "\">\n"
      << "      <subject_name>" << escape_xml(subject_name) << "</subject_name>\n"
      << "      <validity>\n"
      << "        <not_before>" << validity.not_before << "</not_before>\n"
      << "        <not_after>" << validity.not_after << "</not_after>\n"
      << "      </validity>\n";
  // Every identity may announce its process's nodes to ROS 2 tools and read the others'
  // (implicit_topics.hpp).
  std::vector<std::string> publish = g.publish;
  std::vector<std::string> subscribe = g.subscribe;
  publish.emplace_back(kRos2GraphTopic);
  subscribe.emplace_back(kRos2GraphTopic);
  out << "      <allow_rule>\n";
  domains_xml(out, p, "        ");
  topics_xml(out, "publish", publish);
  topics_xml(out, "subscribe", subscribe);
  out << "      </allow_rule>\n";
  out << "      <default>DENY</default>\n"
      << "    </grant>\n"
      << "  </permissions>\n"
      << "</dds>\n";
  return out.str();
}

}  // namespace pmlsm::security
