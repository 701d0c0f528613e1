// The security policy (configs/security/policy.yaml): which identity may publish and subscribe
// which topic, and how the domain protects its traffic; and the two DDS Security documents made
// from it (OMG DDS Security 1.1, 9.4.1.2 governance and 9.4.1.3 permissions, the XML that Fast
// DDS's builtin Access-Permissions plugin reads). Pure: no DDS, no OpenSSL.
#pragma once

#include <stdexcept>
#include <string>
#include <vector>

namespace pmlsm::security {

/// Bad security input (policy, keystore, identity): the message names the file and the item;
/// programs exit with code 2.
class SecurityError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

enum class Protection { kNone, kSign, kEncrypt };

/// "NONE", "SIGN", "ENCRYPT": the governance document's spelling.
const char* protection_name(Protection p);

/// What one identity may do. Topic names are DDS names ("rt/pmlsm/motor_feedback").
struct Grant {
  std::string identity;
  std::vector<std::string> publish;
  std::vector<std::string> subscribe;
  /// A container's identity (policy `containers:`): the identities whose union it holds; empty
  /// for a node's.
  std::vector<std::string> members;
};

struct Policy {
  /// Payload of every user topic: encrypted (AES-GCM). Only signed (GMAC) is what the standard
  /// also allows, but Fast DDS 2.9.1 drops such payloads at every receiver: parse_policy
  /// refuses it.
  Protection data_protection = Protection::kEncrypt;
  /// The submessages of user topics (DATA with its sequence number, HEARTBEAT, ACKNACK, GAP)
  /// as a whole, on top of the payload's own protection. Costs a second cipher pass on every
  /// submessage: about twice the chain latency here (README, Security).
  Protection metadata_protection = Protection::kEncrypt;
  /// Discovery (SEDP) and liveliness (WLP) traffic.
  Protection discovery_protection = Protection::kEncrypt;
  Protection liveliness_protection = Protection::kEncrypt;
  /// Whole RTPS messages (a second layer over all of the above; off by default: it costs a
  /// second cipher pass per message and hides nothing the others leave open but the GUIDs).
  Protection rtps_protection = Protection::kNone;
  /// Domains the documents cover (inclusive).
  int domain_min = 0;
  int domain_max = 232;
  std::vector<Grant> grants;

  /// nullptr when the policy has no grant for `identity`.
  const Grant* find(const std::string& identity) const;
};

/// What a policy may name: the project's topics (DDS names) and node identities.
struct PolicyVocabulary {
  std::vector<std::string> topics;
  std::vector<std::string> identities;
};

/// "rt/pmlsm/x", "/pmlsm/x" and "pmlsm/x" -> "rt/pmlsm/x"; anything else unchanged.
std::string dds_topic_name(const std::string& name);

/// Parses a policy (YAML text; `origin` names it in errors). A topic list of "/pmlsm/*" alone
/// is every topic of the vocabulary. Unknown or duplicated keys, an
/// unknown topic or identity, a topic listed twice for one identity, a bad protection kind or
/// domain range: SecurityError naming origin, key path and value.
Policy parse_policy(const std::string& yaml_text, const std::string& origin, const PolicyVocabulary& vocabulary);

/// Reads and parses `path`. @throws SecurityError (also for an unreadable file).
Policy load_policy(const std::string& path, const PolicyVocabulary& vocabulary);

/// The governance document: authentication required (no unauthenticated participant joins),
/// join access control, the policy's protection kinds, read and write access control on every
/// topic.
std::string governance_xml(const Policy& policy);

/// Validity of a permissions grant, as "YYYY-MM-DDThh:mm:ss" (UTC).
struct Validity {
  std::string not_before;
  std::string not_after;
};

/// The permissions document of one identity: its subject name (as in its certificate, RFC 2253
/// "CN=controller"), validity, the topics it may publish and subscribe on the policy's
/// domains, everything else denied.
std::string permissions_xml(const Policy& policy, const Grant& grant, const std::string& subject_name,
                            const Validity& validity);

}  // namespace pmlsm::security
