// Every decoder and the SDO server over every command byte and DLC: a frame either decodes or
// gives an error with a text, never a throw (the functions are noexcept: a throw would end the
// test program).
#include <gtest/gtest.h>

#include <cstring>

#include "pmlsm/canopen/bytes.hpp"
#include "pmlsm/canopen/cia402_dictionary.hpp"
#include "pmlsm/canopen/emcy.hpp"
#include "pmlsm/canopen/nmt.hpp"
#include "pmlsm/canopen/pdo.hpp"
#include "pmlsm/canopen/sdo_server.hpp"
#include "pmlsm/canopen/sync.hpp"

namespace {

using namespace pmlsm::canopen;

bool well_formed(const Status& s) { return s.ok() ? std::strlen(s.detail) == 0 : std::strlen(s.detail) > 0; }

TEST(MalformedFramesTest, EveryCommandByteAndDlcDecodesOrGivesAnError) {
  const NodeId node(5);
  ObjectDictionary od = make_cia402_dictionary(node);
  SdoServer server(od, node);
  const PdoMap rpdo = read_pdo_map(od, 0x1600).value;
  int sdo_errors = 0;
  for (int dlc = 0; dlc <= 15; ++dlc) {
    for (int command = 0; command <= 0xFF; ++command) {
      CanFrame f = make_frame(0, static_cast<std::uint8_t>(dlc));
      f.data = {static_cast<std::uint8_t>(command), 0x40, 0x60, 0x00, 0xFF, 0xFF, 0xFF, 0xFF};

      f.id = sdo_rx_cob_id(node);
      const auto request = parse_sdo_request(f);
      EXPECT_TRUE(well_formed(request));
      sdo_errors += !request.ok();
      const SdoServerResult answer = server.handle(f);
      EXPECT_TRUE(well_formed(answer.status));
      // The server answers everything but the client's abort (and DLCs over 8, not CAN frames).
      if (dlc <= 8 && !(request.ok() && request.value.kind == SdoRequestKind::kAbort)) {
        EXPECT_TRUE(answer.respond) << "command " << command << " dlc " << dlc;
      }
      if (!request.ok() && dlc <= 8) {
        EXPECT_EQ(answer.response.data[0], kSdoAbort);
        EXPECT_EQ(get_u32_le(answer.response.data, 4), kAbortCommandSpecifier);
      }

      f.id = sdo_tx_cob_id(node);
      EXPECT_TRUE(well_formed(parse_sdo_response(f)));
      f.id = kCobIdNmt;
      EXPECT_TRUE(well_formed(decode_nmt(f)));
      f.id = kCobIdSync;
      EXPECT_TRUE(well_formed(decode_sync(f)));
      f.id = emcy_cob_id(node);
      EXPECT_TRUE(well_formed(decode_emcy(f)));
      f.id = heartbeat_cob_id(node);
      EXPECT_TRUE(well_formed(decode_heartbeat(f)));
      f.id = rpdo_cob_id(1, node);
      const Status unpacked = unpack_pdo(rpdo, od, f);
      EXPECT_TRUE(well_formed(unpacked));
      EXPECT_EQ(unpacked.ok(), dlc == 4);
    }
  }
  EXPECT_GT(sdo_errors, 0);
}

TEST(MalformedFramesTest, ErrorNames) {
  EXPECT_STREQ(to_string(Error::kNone), "no error");
  EXPECT_STREQ(to_string(Error::kWrongDlc), "wrong DLC");
  EXPECT_STREQ(to_string(Error::kUnknownCommand), "unknown command");
  EXPECT_STREQ(to_string(Error::kSegmentedNotSupported), "segmented transfer not supported");
  EXPECT_STREQ(to_string(Error::kBlockNotSupported), "block transfer not supported");
  EXPECT_STREQ(to_string(Error::kPdoMapping), "invalid PDO mapping");
  EXPECT_STREQ(to_string(static_cast<Error>(200)), "unknown");
}

}  // namespace
