// A law whose registration line names another folder (never compiled: the configuration stops).
#pragma once

PMLSM_COMPENSATOR(spring_damper, Damper);
