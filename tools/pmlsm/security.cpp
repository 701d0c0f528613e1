// `pmlsm security`: the DDS Security keystore, in the style of `ros2 security`.
//   pmlsm security create DIR [--policy FILE]             CAs, governance, every identity of the policy
//   pmlsm security create-identity DIR NAME... [--policy] new (or rotated) identities
//   pmlsm security update-permissions DIR [--policy]      documents signed again after a policy change
//   pmlsm security check DIR [NAME...]                     what is wrong with each identity
//   pmlsm security list DIR                                the identities in it
// Layout and why two CAs: common/security/include/pmlsm/security/keystore_layout.hpp.
#include "pmlsm/util/data_files.hpp"
#include <iostream>
#include <memory>

#include "commands.hpp"
#include "pmlsm/components/registered_names.hpp"
#include "pmlsm/dds/catalog.hpp"
#include "pmlsm/security/keystore.hpp"

namespace pmlsm::tools {
namespace {

/// Every program that opens a participant, by the identity it uses: the registered components
/// (their names), the tool's command groups, the launcher and the agent. The names a policy may
/// grant to.
std::vector<std::string> node_identities() {
  std::vector<std::string> names(components::kRegisteredNames.begin(), components::kRegisteredNames.end());
  for (const char* tool : {"pmlsm_topic", "pmlsm_record", "pmlsm_play", "pmlsm_drive", "pmlsm_setpoint", "pmlsm_param",
                           "launcher", "launch_agent"}) {
    names.emplace_back(tool);
  }
  return names;
}

security::Policy load(const std::string& path) {
  security::PolicyVocabulary vocabulary;
  for (const auto& entry : dds::catalog()) vocabulary.topics.emplace_back(entry.spec.name);
  vocabulary.identities = node_identities();
  return security::load_policy(path, vocabulary);
}

struct SecurityOptions {
  std::string keystore;
  std::string policy = data_file("configs/security/policy.yaml");
  std::vector<std::string> names;
  security::KeystoreOptions validity;
};

int run_create(const SecurityOptions& o) {
  const auto policy = load(o.policy);
  const security::KeystoreLayout keystore(o.keystore);
  security::create_keystore(keystore, policy, o.validity);
  for (const auto& grant : policy.grants) security::create_identity(keystore, policy, grant.identity, o.validity);
  std::cout << "keystore " << o.keystore << ": identity and permissions CAs, governance, " << policy.grants.size()
            << " identities from " << o.policy << "\n"
            << "keep " << keystore.private_dir() << " (the CA keys) off the machines that run nodes\n";
  return kExitOk;
}

int run_create_identity(const SecurityOptions& o) {
  const auto policy = load(o.policy);
  const security::KeystoreLayout keystore(o.keystore);
  for (const auto& name : o.names) {
    if (policy.find(name) == nullptr) {
      throw security::SecurityError(o.policy + ": no grant for identity '" + name + "' under identities:");
    }
  }
  for (const auto& name : o.names) {
    security::create_identity(keystore, policy, name, o.validity);
    std::cout << keystore.identity_dir(name) << ": new key, certificate and permissions\n";
  }
  return kExitOk;
}

int run_update_permissions(const SecurityOptions& o) {
  const auto policy = load(o.policy);
  const auto names = security::update_permissions(security::KeystoreLayout(o.keystore), policy);
  std::cout << "governance and the permissions of " << names.size() << " identities signed again from " << o.policy
            << "\n";
  return kExitOk;
}

int run_check(const SecurityOptions& o) {
  const security::KeystoreLayout keystore(o.keystore);
  const auto names = o.names.empty() ? security::list_identities(keystore) : o.names;
  if (names.empty()) throw security::SecurityError("keystore '" + o.keystore + "' holds no identity");
  std::size_t bad = 0;
  for (const auto& name : names) {
    const auto problems = security::check_identity(keystore, name);
    std::cout << name << ": " << (problems.empty() ? "ok" : "REFUSED") << "\n";
    for (const auto& p : problems) std::cout << "    " << p << "\n";
    bad += problems.empty() ? 0 : 1;
  }
  return bad == 0 ? kExitOk : kExitBadConfig;
}

int run_list(const SecurityOptions& o) {
  for (const auto& name : security::list_identities(security::KeystoreLayout(o.keystore))) std::cout << name << "\n";
  return kExitOk;
}

}  // namespace

void add_security_command(CLI::App& app, int& exit_code) {
  auto* sec =
      app.add_subcommand("security", "DDS Security keystore: CAs, identities, signed governance and permissions");
  sec->require_subcommand(1);
  auto o = std::make_shared<SecurityOptions>();
  const auto add_policy = [&o](CLI::App* cmd) {
    cmd->add_option("--policy", o->policy, "Security policy (YAML)")->capture_default_str();
  };
  const auto add_days = [&o](CLI::App* cmd, bool ca) {
    if (ca) {
      cmd->add_option("--ca-days", o->validity.ca_valid_days, "Validity of the two CAs [days]")
          ->capture_default_str()
          ->check(CLI::Range(1, 36500));
    }
    cmd->add_option("--identity-days", o->validity.identity_valid_days, "Validity of identity certificates [days]")
        ->capture_default_str()
        ->check(CLI::Range(1, 36500));
  };

  auto* create = sec->add_subcommand("create", "A new keystore: CAs, governance, every identity the policy names");
  create->add_option("keystore", o->keystore, "Folder (created; refused when it holds a keystore)")->required();
  add_policy(create);
  add_days(create, true);
  create->callback([o, &exit_code] { exit_code = run_create(*o); });

  auto* identity = sec->add_subcommand("create-identity",
                                       "New key, certificate and permissions for identities "
                                       "(replaces existing ones: rotation)");
  identity->add_option("keystore", o->keystore, "Keystore folder")->required()->check(CLI::ExistingDirectory);
  identity->add_option("names", o->names, "Identity names (as in the policy)")->required();
  add_policy(identity);
  add_days(identity, false);
  identity->callback([o, &exit_code] { exit_code = run_create_identity(*o); });

  auto* update = sec->add_subcommand("update-permissions",
                                     "Governance and every identity's permissions signed again from the policy");
  update->add_option("keystore", o->keystore, "Keystore folder")->required()->check(CLI::ExistingDirectory);
  add_policy(update);
  update->callback([o, &exit_code] { exit_code = run_update_permissions(*o); });

  auto* check = sec->add_subcommand("check",
                                    "Verifies identities (default: all): files, certificates, keys, "
                                    "signatures; exit 2 when any is refused");
  check->add_option("keystore", o->keystore, "Keystore folder")->required()->check(CLI::ExistingDirectory);
  check->add_option("names", o->names, "Identities to check");
  check->callback([o, &exit_code] { exit_code = run_check(*o); });

  auto* list = sec->add_subcommand("list", "The identities in a keystore");
  list->add_option("keystore", o->keystore, "Keystore folder")->required()->check(CLI::ExistingDirectory);
  list->callback([o, &exit_code] { exit_code = run_list(*o); });
}

}  // namespace pmlsm::tools
