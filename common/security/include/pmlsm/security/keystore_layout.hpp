// Where a keystore keeps what (header only, no OpenSSL: participants read it too).
//
//   KEYSTORE/
//     public/identity_ca.cert.pem       trusted issuer of every identity certificate
//     public/permissions_ca.cert.pem    trusted signer of the governance and permissions documents
//     public/governance.xml             the governance document, and signed (S/MIME):
//     public/governance.p7s
//     private/identity_ca.key.pem       0600; only `pmlsm security` needs them: keep them off the rig
//     private/permissions_ca.key.pem    0600
//     identities/<name>/cert.pem        the node's certificate, subject CN=<name>
//     identities/<name>/key.pem         0600, its private key
//     identities/<name>/permissions.xml what it may publish and subscribe, and signed:
//     identities/<name>/permissions.p7s
//
// Two CAs, not one: an identity's key can then never sign a permissions document that verifies
// (with one CA it can, where the verifier accepts any signer chaining to the CA: CVE-2023-24010).
#pragma once

#include <string>
#include <utility>
#include <vector>

namespace pmlsm::security {

class KeystoreLayout {
 public:
  explicit KeystoreLayout(std::string root) : root_(std::move(root)) {
    while (root_.size() > 1 && root_.back() == '/') root_.pop_back();
  }
  const std::string& root() const { return root_; }
  std::string public_dir() const { return root_ + "/public"; }
  std::string private_dir() const { return root_ + "/private"; }
  std::string identity_ca_cert() const { return public_dir() + "/identity_ca.cert.pem"; }
  std::string permissions_ca_cert() const { return public_dir() + "/permissions_ca.cert.pem"; }
  std::string governance_xml() const { return public_dir() + "/governance.xml"; }
  std::string governance_p7s() const { return public_dir() + "/governance.p7s"; }
  std::string identity_ca_key() const { return private_dir() + "/identity_ca.key.pem"; }
  std::string permissions_ca_key() const { return private_dir() + "/permissions_ca.key.pem"; }
  std::string identities_dir() const { return root_ + "/identities"; }
  std::string identity_dir(const std::string& name) const { return identities_dir() + "/" + name; }
  std::string identity_cert(const std::string& name) const { return identity_dir(name) + "/cert.pem"; }
  std::string identity_key(const std::string& name) const { return identity_dir(name) + "/key.pem"; }
  std::string permissions_xml(const std::string& name) const { return identity_dir(name) + "/permissions.xml"; }
  std::string permissions_p7s(const std::string& name) const { return identity_dir(name) + "/permissions.p7s"; }

  /// The DDS Security participant properties of identity `name` (OMG DDS Security 1.1,
  /// 9.3.1 and 9.4.1): plugin choice and the file:// URIs of its six files.
  std::vector<std::pair<std::string, std::string>> participant_properties(const std::string& name) const {
    return {
        {"dds.sec.auth.plugin", "builtin.PKI-DH"},
        {"dds.sec.auth.builtin.PKI-DH.identity_ca", "file://" + identity_ca_cert()},
        {"dds.sec.auth.builtin.PKI-DH.identity_certificate", "file://" + identity_cert(name)},
        {"dds.sec.auth.builtin.PKI-DH.private_key", "file://" + identity_key(name)},
        {"dds.sec.access.plugin", "builtin.Access-Permissions"},
        {"dds.sec.access.builtin.Access-Permissions.permissions_ca", "file://" + permissions_ca_cert()},
        {"dds.sec.access.builtin.Access-Permissions.governance", "file://" + governance_p7s()},
        {"dds.sec.access.builtin.Access-Permissions.permissions", "file://" + permissions_p7s(name)},
        {"dds.sec.crypto.plugin", "builtin.AES-GCM-GMAC"},
    };
  }

  /// The files a participant of identity `name` reads, each with what it is (for errors).
  std::vector<std::pair<std::string, std::string>> participant_files(const std::string& name) const {
    return {{identity_ca_cert(), "identity CA certificate"},
            {identity_cert(name), "identity certificate of '" + name + "'"},
            {identity_key(name), "private key of '" + name + "'"},
            {permissions_ca_cert(), "permissions CA certificate"},
            {governance_p7s(), "signed governance document"},
            {permissions_p7s(name), "signed permissions of '" + name + "'"}};
  }

 private:
  std::string root_;
};

}  // namespace pmlsm::security
