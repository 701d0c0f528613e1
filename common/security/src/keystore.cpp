#include "pmlsm/security/keystore.hpp"

#include <sys/stat.h>

#include <algorithm>
#include <cerrno>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <sstream>

#include "pmlsm/util/atomic_file.hpp"

namespace pmlsm::security {
namespace fs = std::filesystem;
namespace {

constexpr unsigned kPrivateMode = 0600;
constexpr std::int64_t kDay = 24 * 3600;

void make_dir(const std::string& path, fs::perms perms) {
  std::error_code ec;
  fs::create_directories(path, ec);
  if (ec) throw SecurityError("cannot create the folder '" + path + "': " + ec.message());
  fs::permissions(path, perms, ec);
  if (ec) throw SecurityError("cannot set the mode of '" + path + "': " + ec.message());
}

void write(const std::string& path, const std::string& contents, unsigned mode = 0644) {
  try {
    write_file_atomically(path, contents, mode);
  } catch (const AtomicWriteError& e) {
    throw SecurityError(e.what());
  }
}

CertifiedKey read_pair(const std::string& cert, const std::string& key, const std::string& what) {
  return CertifiedKey{read_file(cert, what + " certificate"), read_file(key, what + " private key")};
}

const Grant& grant_for(const Policy& policy, const std::string& name) {
  const Grant* grant = policy.find(name);
  if (grant == nullptr) {
    throw SecurityError("the security policy has no grant for identity '" + name +
                        "': add it under identities: in the policy first");
  }
  return *grant;
}

void sign_permissions(const KeystoreLayout& ks, const Policy& policy, const std::string& name,
                      const CertifiedKey& permissions_ca) {
  const std::string cert = read_file(ks.identity_cert(name), "identity certificate of '" + name + "'");
  Validity validity;
  validity_strings(cert, validity.not_before, validity.not_after);
  const std::string xml = permissions_xml(policy, grant_for(policy, name), subject_name(cert), validity);
  write(ks.permissions_xml(name), xml);
  write(ks.permissions_p7s(name), sign_smime(xml, permissions_ca));
}

void sign_governance(const KeystoreLayout& ks, const Policy& policy, const CertifiedKey& permissions_ca) {
  const std::string xml = governance_xml(policy);
  write(ks.governance_xml(), xml);
  write(ks.governance_p7s(), sign_smime(xml, permissions_ca));
}

}  // namespace

std::string read_file(const std::string& path, const std::string& what) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw SecurityError("cannot read the " + what + " '" + path + "': " + std::strerror(errno));
  std::ostringstream text;
  text << in.rdbuf();
  return text.str();
}

void create_keystore(const KeystoreLayout& ks, const Policy& policy, const KeystoreOptions& options) {
  if (fs::exists(ks.identity_ca_key()) || fs::exists(ks.permissions_ca_key()) || fs::exists(ks.identity_ca_cert())) {
    throw SecurityError("'" + ks.root() + "' already holds a keystore (" + ks.identity_ca_cert() +
                        "); nothing was overwritten");
  }
  make_dir(ks.root(), fs::perms::owner_all | fs::perms::group_read | fs::perms::group_exec | fs::perms::others_read |
                          fs::perms::others_exec);
  make_dir(ks.public_dir(), fs::perms::owner_all | fs::perms::group_read | fs::perms::group_exec |
                                fs::perms::others_read | fs::perms::others_exec);
  make_dir(ks.private_dir(), fs::perms::owner_all);
  make_dir(ks.identities_dir(), fs::perms::owner_all | fs::perms::group_read | fs::perms::group_exec |
                                    fs::perms::others_read | fs::perms::others_exec);
  // Valid from an hour ago: a host whose clock is a little behind still accepts it.
  const ValidityWindow validity{-3600, options.ca_valid_days * kDay};
  const auto identity_ca = make_ca("pmlsm identity CA", validity);
  const auto permissions_ca = make_ca("pmlsm permissions CA", validity);
  write(ks.identity_ca_key(), identity_ca.key_pem, kPrivateMode);
  write(ks.identity_ca_cert(), identity_ca.cert_pem);
  write(ks.permissions_ca_key(), permissions_ca.key_pem, kPrivateMode);
  write(ks.permissions_ca_cert(), permissions_ca.cert_pem);
  sign_governance(ks, policy, permissions_ca);
}

void create_identity(const KeystoreLayout& ks, const Policy& policy, const std::string& name,
                     const KeystoreOptions& options) {
  grant_for(policy, name);  // before anything is written
  const auto identity_ca = read_pair(ks.identity_ca_cert(), ks.identity_ca_key(), "identity CA");
  const auto permissions_ca = read_pair(ks.permissions_ca_cert(), ks.permissions_ca_key(), "permissions CA");
  make_dir(ks.identity_dir(name), fs::perms::owner_all | fs::perms::group_read | fs::perms::group_exec |
                                      fs::perms::others_read | fs::perms::others_exec);
  const auto identity = make_identity(name, identity_ca, ValidityWindow{-3600, options.identity_valid_days * kDay});
  // The key first: a certificate without its key is useless, a key without its certificate harmless.
  write(ks.identity_key(name), identity.key_pem, kPrivateMode);
  write(ks.identity_cert(name), identity.cert_pem);
  sign_permissions(ks, policy, name, permissions_ca);
}

std::vector<std::string> update_permissions(const KeystoreLayout& ks, const Policy& policy) {
  const auto permissions_ca = read_pair(ks.permissions_ca_cert(), ks.permissions_ca_key(), "permissions CA");
  const auto names = list_identities(ks);
  for (const auto& name : names) grant_for(policy, name);  // all or nothing
  sign_governance(ks, policy, permissions_ca);
  for (const auto& name : names) sign_permissions(ks, policy, name, permissions_ca);
  return names;
}

std::vector<std::string> list_identities(const KeystoreLayout& ks) {
  std::vector<std::string> names;
  std::error_code ec;
  for (const auto& entry : fs::directory_iterator(ks.identities_dir(), ec)) {
    if (entry.is_directory()) names.push_back(entry.path().filename().string());
  }
  std::sort(names.begin(), names.end());
  return names;
}

std::vector<std::string> check_identity(const KeystoreLayout& ks, const std::string& name) {
  std::vector<std::string> problems;
  std::vector<std::string> contents;
  for (const auto& [path, what] : ks.participant_files(name)) {
    try {
      contents.push_back(read_file(path, what));
    } catch (const SecurityError& e) {
      problems.push_back(e.what());
      contents.emplace_back();
    }
  }
  if (!problems.empty()) return problems;
  const std::string& identity_ca = contents[0];
  const std::string& cert = contents[1];
  const std::string& key = contents[2];
  const std::string& permissions_ca = contents[3];
  std::string why;
  if (!verify_certificate(cert, identity_ca, why)) {
    problems.push_back(ks.identity_cert(name) + ": not valid under the identity CA: " + why);
  }
  if (!key_matches(cert, key)) problems.push_back(ks.identity_key(name) + ": not the key of " + ks.identity_cert(name));
  struct stat st {};
  if (::stat(ks.identity_key(name).c_str(), &st) == 0 && (st.st_mode & 077) != 0) {
    problems.push_back(ks.identity_key(name) + ": readable by others (mode " + std::to_string((st.st_mode >> 6) & 7) +
                       std::to_string((st.st_mode >> 3) & 7) + std::to_string(st.st_mode & 7) + "; chmod 600)");
  }
  if (verify_smime(contents[4], permissions_ca, why).empty()) {
    problems.push_back(ks.governance_p7s() + ": " + why);
  }
  const std::string permissions = verify_smime(contents[5], permissions_ca, why);
  if (permissions.empty()) {
    problems.push_back(ks.permissions_p7s(name) + ": " + why);
  } else {
    std::string subject;
    try {
      subject = subject_name(cert);
    } catch (const SecurityError& e) {
      subject = "?";
    }
    if (permissions.find("<subject_name>" + subject + "</subject_name>") == std::string::npos) {
      problems.push_back(ks.permissions_p7s(name) + ": grants nothing to the certificate's subject " + subject);
    }
  }
  return problems;
}

}  // namespace pmlsm::security
