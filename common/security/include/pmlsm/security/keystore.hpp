// Making and checking a keystore (layout: keystore_layout.hpp): what `pmlsm security` does.
#pragma once

#include <string>
#include <vector>

#include "pmlsm/security/keystore_layout.hpp"
#include "pmlsm/security/pki.hpp"
#include "pmlsm/security/policy.hpp"

namespace pmlsm::security {

struct KeystoreOptions {
  int ca_valid_days = 3650;
  int identity_valid_days = 365;
};

/// Creates the two CAs and the signed governance document in `root` (made if missing).
/// @throws SecurityError when root already holds a CA (nothing is overwritten) or a write fails.
void create_keystore(const KeystoreLayout& keystore, const Policy& policy, const KeystoreOptions& options);

/// Writes (or replaces: rotation) identity `name`: a new key and certificate from the identity
/// CA, and its permissions from the policy's grant, signed by the permissions CA.
/// @throws SecurityError when the policy has no grant for `name` or a CA file is missing.
void create_identity(const KeystoreLayout& keystore, const Policy& policy, const std::string& name,
                     const KeystoreOptions& options);

/// Signs the governance document and every existing identity's permissions again from
/// `policy` (after a policy change; keys and certificates stay). @return the identities updated.
std::vector<std::string> update_permissions(const KeystoreLayout& keystore, const Policy& policy);

/// Everything wrong with identity `name` in the keystore, as one line each (empty: fine): a
/// missing or unreadable file, a certificate not from the identity CA or out of its validity,
/// a key that is not the certificate's or readable by others, a document whose signature does
/// not verify against the permissions CA, a permissions subject that is not the certificate's.
std::vector<std::string> check_identity(const KeystoreLayout& keystore, const std::string& name);

/// The identities present in the keystore (sub-folders of identities/), sorted.
std::vector<std::string> list_identities(const KeystoreLayout& keystore);

/// Reads a whole file. @throws SecurityError naming the file and `what` it is.
std::string read_file(const std::string& path, const std::string& what);

}  // namespace pmlsm::security
