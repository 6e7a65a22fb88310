// A component's safety stop, as its service's retained state says it (a motor's `stop_reason`).

/** The safety stop a component's retained state says (`stop_reason`: watchdog, …), or null. */
export function safetyStop(retained: unknown): string | null {
  if (!retained || typeof retained !== "object" || Array.isArray(retained)) return null;
  const reason = (retained as Record<string, unknown>).stop_reason;
  return typeof reason === "string" && reason ? reason : null;
}
